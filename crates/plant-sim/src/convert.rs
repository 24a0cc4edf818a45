//! ADC and DAC: mid-tread quantisers with two's-complement code ranges and clipping.

/// A `bits`-bit converter spanning ±`range_v` volts; `bits = 0` is an ideal converter (no
/// quantisation, no clipping) for analysis.
///
/// ```
/// use plant_sim::convert::Quantizer;
/// let adc = Quantizer::new(16, 4.096);
/// assert_eq!(adc.lsb_v(), 8.192 / 65536.0);
/// assert_eq!(adc.code(1.0), (8000, false));
/// assert_eq!(adc.code(5.0), (32767, true)); // clipped
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quantizer {
    lsb: f64,
    inv_lsb: f64,
    min_code: i32,
    max_code: i32,
}

impl Quantizer {
    /// A converter with `bits` ∈ [1, 31] bits over ±`range_v` V (0: ideal).
    pub fn new(bits: u32, range_v: f64) -> Self {
        if bits == 0 {
            return Quantizer {
                lsb: 0.0,
                inv_lsb: 0.0,
                min_code: 0,
                max_code: 0,
            };
        }
        let half = 1i64 << (bits.min(31) - 1);
        let lsb = 2.0 * range_v / (2 * half) as f64;
        Quantizer {
            lsb,
            inv_lsb: 1.0 / lsb, // a multiply in the tick; exact for the ±4.096 V ADC
            min_code: -half as i32,
            max_code: (half - 1) as i32,
        }
    }

    /// Whether this is the ideal converter.
    pub fn is_ideal(&self) -> bool {
        self.lsb == 0.0
    }

    /// The converted value in V and whether it clipped.
    #[inline]
    pub fn convert(&self, volts: f64) -> (f64, bool) {
        if self.is_ideal() {
            return (volts, false);
        }
        let (code, clipped) = self.code(volts);
        (self.volts(code), clipped)
    }

    /// Volts per code step.
    pub fn lsb_v(&self) -> f64 {
        self.lsb
    }

    /// The code for `volts` (nearest, ties away from zero) and whether it clipped. NaN → 0.
    #[inline]
    pub fn code(&self, volts: f64) -> (i32, bool) {
        let raw = (volts * self.inv_lsb).round();
        if raw.is_nan() {
            return (0, true);
        }
        let clipped = raw < self.min_code as f64 || raw > self.max_code as f64;
        (
            raw.clamp(self.min_code as f64, self.max_code as f64) as i32,
            clipped,
        )
    }

    /// Volts of `code`.
    #[inline]
    pub fn volts(&self, code: i32) -> f64 {
        code as f64 * self.lsb
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn code_steps_and_limits_are_exact() {
        let adc = Quantizer::new(16, 4.096);
        let lsb = 8.192 / 65536.0;
        assert_eq!(adc.code(0.49 * lsb), (0, false));
        assert_eq!(adc.code(0.51 * lsb), (1, false));
        assert_eq!(adc.code(-1.5 * lsb), (-2, false));
        assert_eq!(adc.code(4.096 - lsb), (32767, false));
        assert_eq!(adc.code(4.096), (32767, true));
        assert_eq!(adc.code(-4.096), (-32768, false));
        assert_eq!(adc.code(-4.1), (-32768, true));
        assert_eq!(adc.code(f64::NAN), (0, true));
        let dac = Quantizer::new(18, 10.0);
        assert_eq!(dac.lsb_v(), 20.0 / 262144.0);
        assert_eq!(dac.code(10.0), (131071, true));
        assert_eq!(dac.convert(10.0), (dac.volts(131071), true));
        let ideal = Quantizer::new(0, 10.0);
        assert_eq!(ideal.convert(123.456), (123.456, false));
    }
}
