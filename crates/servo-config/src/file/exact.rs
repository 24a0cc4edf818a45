//! Fixed-length arrays read from files: exactly `N` numbers, or an error saying how many there
//! were (serde's arrays take the first `N` of a longer TOML array and drop the rest silently).

use serde::{de::Error, Deserialize, Deserializer};

/// `N` numbers, exactly (`#[serde(deserialize_with = "…")]`).
pub fn exact_array<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<[f64; N], D::Error> {
    let v = Vec::<f64>::deserialize(d)?;
    exactly(&v)
}

/// A list of arrays of `N` numbers, each exactly.
pub fn exact_arrays<'de, D: Deserializer<'de>, const N: usize>(
    d: D,
) -> Result<Vec<[f64; N]>, D::Error> {
    Vec::<Vec<f64>>::deserialize(d)?
        .iter()
        .map(|v| exactly(v))
        .collect()
}

fn exactly<E: Error, const N: usize>(v: &[f64]) -> Result<[f64; N], E> {
    v.try_into().map_err(|_| {
        E::custom(format!(
            "expected an array of {N} numbers, found {}",
            v.len()
        ))
    })
}

#[cfg(test)]
mod tests {
    #[derive(serde::Deserialize, Debug)]
    struct T {
        #[serde(deserialize_with = "super::exact_array")]
        x: [f64; 2],
        #[serde(deserialize_with = "super::exact_arrays")]
        s: Vec<[f64; 3]>,
    }

    #[test]
    fn extra_or_missing_numbers_are_refused() {
        let ok: T = toml::from_str("x = [1.0, 2.0]\ns = [[1.0, 2.0, 3.0]]").unwrap();
        assert_eq!((ok.x, ok.s), ([1.0, 2.0], vec![[1.0, 2.0, 3.0]]));
        for (text, found) in [
            ("x = [1.0, 2.0, 3.0]\ns = []", "found 3"),
            ("x = [1.0]\ns = []", "found 1"),
            ("x = [1.0, 2.0]\ns = [[1.0, 2.0, 3.0, 4.0]]", "found 4"),
        ] {
            let e = toml::from_str::<T>(text).unwrap_err().to_string();
            assert!(e.contains(found), "{e}");
        }
    }
}
