//! SI units of the variables, read from their names' suffixes (`_kg`, `_n_per_m`, `_v`, … —
//! every key of the project states its unit that way), with the base-unit exponents a model
//! description declares.

/// A unit: its name in a model description and its SI base-unit exponents (kg, m, s, A) when
/// they are whole numbers (a noise density per √Hz has none).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Unit {
    /// The unit's name (`N/m`).
    pub name: &'static str,
    /// Exponents of kg, m, s and A (None: not expressible in whole powers).
    pub base: Option<[i8; 4]>,
}

const fn unit(name: &'static str, base: [i8; 4]) -> Unit {
    Unit {
        name,
        base: Some(base),
    }
}

/// Name suffix → unit, longest suffixes first so `_n_s_per_m` is not read as `_per_m`.
const SUFFIXES: &[(&str, Unit)] = &[
    (
        "_v_per_rt_hz",
        Unit {
            name: "V/sqrt(Hz)",
            base: None,
        },
    ),
    (
        "_a_per_rt_hz",
        Unit {
            name: "A/sqrt(Hz)",
            base: None,
        },
    ),
    (
        "_m_per_rt_hz",
        Unit {
            name: "m/sqrt(Hz)",
            base: None,
        },
    ),
    ("_v_per_m_s2", unit("V/(m/s2)", [1, 1, -1, -1])),
    ("_n_s_per_m", unit("N.s/m", [1, 0, -1, 0])),
    ("_n_per_m", unit("N/m", [1, 0, -2, 0])),
    ("_n_per_a", unit("N/A", [1, 1, -2, -1])),
    ("_a_per_v", unit("A/V", [-1, -2, 3, 2])),
    ("_v_per_m", unit("V/m", [1, 1, -3, -1])),
    ("_ohm", unit("Ohm", [1, 2, -3, -2])),
    ("_hz", unit("Hz", [0, 0, -1, 0])),
    ("_kg", unit("kg", [1, 0, 0, 0])),
    ("_s", unit("s", [0, 0, 1, 0])),
    ("_h", unit("H", [1, 2, -2, -2])),
    ("_v", unit("V", [1, 2, -3, -1])),
    ("_a", unit("A", [0, 0, 0, 1])),
    ("_n", unit("N", [1, 1, -2, 0])),
    ("_m", unit("m", [0, 1, 0, 0])),
];

/// The unit a variable's name states (None: a dimensionless or unitless name).
pub fn unit_of(name: &str) -> Option<Unit> {
    SUFFIXES
        .iter()
        .find(|(suffix, _)| name.ends_with(suffix))
        .map(|(_, u)| *u)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn suffixes_name_their_si_units() {
        let name = |n: &str| unit_of(n).map(|u| u.name);
        assert_eq!(name("stage.c2_n_s_per_m"), Some("N.s/m"));
        assert_eq!(name("stage.k2_n_per_m"), Some("N/m"));
        assert_eq!(name("accel.sensitivity_v_per_m_s2"), Some("V/(m/s2)"));
        assert_eq!(name("noise.sensor_v_per_rt_hz"), Some("V/sqrt(Hz)"));
        assert_eq!(name("actuator.coil.inductance_h"), Some("H"));
        assert_eq!(name("dac_v"), Some("V"));
        assert_eq!(name("tool_position_m"), Some("m"));
        assert_eq!(name("actuator.current_damping"), None);
        // V = kg·m²·s⁻³·A⁻¹; N/A·(A/V) = N/V, so their exponents add to N's minus V's.
        let [kg, m, s, a] = unit_of("x_v").unwrap().base.unwrap();
        assert_eq!([kg, m, s, a], [1, 2, -3, -1]);
        let na = unit_of("x_n_per_a").unwrap().base.unwrap();
        let av = unit_of("x_a_per_v").unwrap().base.unwrap();
        let n = unit_of("x_n").unwrap().base.unwrap();
        let v = unit_of("x_v").unwrap().base.unwrap();
        for i in 0..4 {
            assert_eq!(na[i] + av[i], n[i] - v[i]);
        }
    }
}
