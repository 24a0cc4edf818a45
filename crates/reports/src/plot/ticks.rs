//! Tick labels: plain numbers, decades on long log axes, as many decimals as a linear axis
//! needs.

/// A tick label as a plain number: up to four significant digits without trailing zeros
/// ("350", "0.25", "−12.5"), scientific only far from 1 ("1e-9", "2.5e6").
pub fn plain(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return if v == 0.0 { "0".into() } else { format!("{v}") };
    }
    let a = v.abs();
    let text = if (1e-3..1e6).contains(&a) {
        let digits = (3 - libm::log10(a).floor() as i32).clamp(0, 6) as usize;
        let t = format!("{a:.digits$}");
        if t.contains('.') {
            t.trim_end_matches('0').trim_end_matches('.').to_owned()
        } else {
            t
        }
    } else {
        let t = format!("{a:.3e}");
        let (m, e) = t.split_once('e').unwrap_or((&t, "0"));
        let m = if m.contains('.') {
            m.trim_end_matches('0').trim_end_matches('.')
        } else {
            m
        };
        format!("{m}e{e}")
    };
    if v < 0.0 {
        format!("−{text}")
    } else {
        text
    }
}

/// Whether `v` is a power of ten (to rounding).
fn is_decade(v: f64) -> bool {
    v > 0.0 && (libm::log10(v) - libm::log10(v).round()).abs() < 1e-9
}

/// The label of tick `v` on an axis over `(lo, hi)`: log axes spanning two decades or more
/// are labelled at decades only; linear axes with as many decimals as their span needs
/// (a 0.05 mm band reads 31.795, not 31.8 three times).
pub(super) fn tick_label(v: f64, log: bool, (lo, hi): (f64, f64)) -> String {
    if log {
        return if hi / lo >= 100.0 && !is_decade(v) {
            String::new()
        } else {
            plain(v)
        };
    }
    let a = v.abs();
    if v == 0.0 || !(1e-3..1e6).contains(&a) {
        return plain(v);
    }
    let decimals =
        (2 - libm::log10((hi - lo).abs().max(1e-12)).floor() as i32).clamp(0, 12) as usize;
    let t = format!("{a:.decimals$}");
    let t = if t.contains('.') {
        t.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        t
    };
    if v < 0.0 && t != "0" {
        format!("−{t}")
    } else {
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_are_plain_numbers_with_the_decimals_their_axis_needs() {
        assert_eq!(plain(-350.0), "−350");
        assert_eq!(plain(0.25), "0.25");
        assert_eq!(plain(1e-9), "1e-9");
        assert_eq!(plain(2.5e6), "2.5e6");
        assert_eq!(plain(1000.0), "1000");
        // Log axes over two decades or more: decades only.
        assert_eq!(tick_label(100.0, true, (10.0, 1e4)), "100");
        assert_eq!(tick_label(200.0, true, (10.0, 1e4)), "");
        assert_eq!(tick_label(200.0, true, (150.0, 900.0)), "200");
        // A narrow linear axis keeps its distinguishing digits.
        assert_eq!(tick_label(31.795, false, (31.78, 31.83)), "31.795");
        assert_eq!(tick_label(31.8, false, (31.78, 31.83)), "31.8");
        assert_eq!(tick_label(-350.0, false, (-400.0, 400.0)), "−350");
    }
}
