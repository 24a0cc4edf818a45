//! The study description: a run configuration (the operating point) plus a `[study]` table
//! naming the controller families, how points are sampled and the parameters that vary.
//!
//! ```toml
//! [plant.noise]                      # any run-configuration table: the operating point
//! sensor_v_per_rt_hz = 1.5e-6
//!
//! [study]
//! name = "flexure"                   # label of the plots
//! controllers = ["h2"]               # h2 | h2-bandwidth | pid
//! bandwidth_hz = 1600.0              # −3 dB bandwidth that h2-bandwidth and pid are tuned to
//! effort_weight_nm_per_v = 1.0       # ρ of the H2 design
//! sampling = "grid"                  # grid | random | latin-hypercube
//! samples = 0                        # points of random and latin-hypercube sampling
//! seed = 1
//! objective = "following"            # the RMS the optimum and map show: following | true
//!
//! [[study.parameter]]
//! key = "plant.stage.k2_n_per_m"     # any numeric key of `servo config --dump`
//! from = 2e3                         # or: values = [1e4, 2e4]
//! to = 2e6
//! points = 13                        # grid points (grid sampling only)
//! spacing = "log"                    # linear | log
//! ```
//!
//! The whole text is the study: a worker given it (a shard, a Ray task) builds every point
//! from it alone, and its SHA-256 names the study in every result file.

use run_config::{sha256_hex, ConfigError, Origin, RunConfig};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The derived key that scales m1 and m2 together to a total moving mass m1 + m2 in kg
/// (thesis §6.5.1 varies "the total moving mass m1 + m2").
pub const MOVING_MASS_KEY: &str = "plant.stage.moving_mass_kg";

/// Most points a study may have (the table of a bigger one belongs in several studies).
pub const MAX_POINTS: u64 = 2_000_000;
/// Most parameters a study may vary.
pub const MAX_PARAMETERS: usize = 32;

/// A controller family: what controller each point gets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Family {
    /// The H2-optimal controller of the point's plant (`servo synth h2`): its bandwidth is the
    /// optimal one (thesis Fig 6-14 a).
    H2,
    /// The H2 controller tuned to the study's `bandwidth_hz`: the design's assumed sensor noise
    /// scaled until the closed loop has that −3 dB bandwidth (thesis Fig 6-14 b tuned We's ω_b).
    H2Bandwidth,
    /// The PID tuned by `servo tune` to `bandwidth_hz` under `pid_ms` and `pid_mt`.
    Pid,
}

impl Family {
    /// The name used in files (`h2`, `h2-bandwidth`, `pid`).
    pub fn name(self) -> &'static str {
        match self {
            Family::H2 => "h2",
            Family::H2Bandwidth => "h2-bandwidth",
            Family::Pid => "pid",
        }
    }
}

/// How the points of a study are chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Sampling {
    /// Every combination of the parameters' values (the last parameter varies fastest).
    Grid,
    /// `samples` independent uniform (log-uniform on log ranges) draws.
    Random,
    /// `samples` Latin-hypercube draws: each parameter's range cut into `samples` strata, each
    /// stratum used once.
    LatinHypercube,
}

/// The error the optimum and the map are about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Objective {
    /// RMS following error (what the sensor reports; thesis Fig 6-14, 6-17).
    Following,
    /// RMS true tool error.
    True,
}

/// Value spacing of a range.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Spacing {
    /// Evenly spaced (uniform draws).
    #[default]
    Linear,
    /// Logarithmically spaced (log-uniform draws); both ends > 0.
    Log,
}

/// One parameter a study varies.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Parameter {
    /// Dotted configuration key (`plant.stage.k2_n_per_m`) or [`MOVING_MASS_KEY`].
    pub key: String,
    /// Explicit values (instead of a range), in the key's unit.
    #[serde(default)]
    pub values: Option<Vec<f64>>,
    /// Range start, in the key's unit.
    #[serde(default)]
    pub from: Option<f64>,
    /// Range end, in the key's unit.
    #[serde(default)]
    pub to: Option<f64>,
    /// Grid points of a range (grid sampling).
    #[serde(default)]
    pub points: Option<u64>,
    /// Spacing of a range.
    #[serde(default)]
    pub spacing: Spacing,
}

/// The `[study]` table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StudyTable {
    /// Label of the study in plots and reports.
    #[serde(default = "default_name")]
    pub name: String,
    /// Controller families; each is an outer dimension of the study.
    #[serde(default = "default_families")]
    pub controllers: Vec<Family>,
    /// −3 dB bandwidth in Hz that `h2-bandwidth` and `pid` are tuned to (thesis: 1600).
    #[serde(default = "default_bandwidth")]
    pub bandwidth_hz: f64,
    /// ρ of the H2 designs: 1 V of command against 1 nm of tool error, nm/V.
    #[serde(default = "default_effort")]
    pub effort_weight_nm_per_v: f64,
    /// Sensitivity bound of the tuned PID.
    #[serde(default = "default_ms")]
    pub pid_ms: f64,
    /// Complementary-sensitivity bound of the tuned PID.
    #[serde(default = "default_mt")]
    pub pid_mt: f64,
    /// How points are chosen.
    #[serde(default = "default_sampling")]
    pub sampling: Sampling,
    /// Points of random and Latin-hypercube sampling (per controller family).
    #[serde(default)]
    pub samples: u64,
    /// Seed of random and Latin-hypercube sampling.
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// The error the optimum and the map are about.
    #[serde(default = "default_objective")]
    pub objective: Objective,
    /// The parameters varied, in order.
    #[serde(default, rename = "parameter")]
    pub parameters: Vec<Parameter>,
}

fn default_name() -> String {
    "study".into()
}
fn default_families() -> Vec<Family> {
    vec![Family::H2]
}
fn default_bandwidth() -> f64 {
    1600.0
}
fn default_effort() -> f64 {
    1.0
}
fn default_ms() -> f64 {
    1.5
}
fn default_mt() -> f64 {
    1.3
}
fn default_sampling() -> Sampling {
    Sampling::Grid
}
fn default_seed() -> u64 {
    1
}
fn default_objective() -> Objective {
    Objective::Following
}

/// A study, parsed and checked.
#[derive(Debug, Clone)]
pub struct Study {
    /// The `[study]` table.
    pub table: StudyTable,
    /// The operating point: the run configuration of the file (defaults elsewhere), as a TOML
    /// tree that each point edits.
    pub base: toml::Value,
    /// The operating point's configuration.
    pub base_config: RunConfig,
    /// Where it came from (errors name the file and line).
    pub origin: Origin,
    /// The whole description.
    pub text: String,
    /// SHA-256 (hex) of `text`: the study's identity in every result file.
    pub sha256: String,
}

impl Study {
    /// Reads and checks the study file `path`.
    pub fn from_file(path: &Path) -> Result<Self, ConfigError> {
        let text = run_config::input_file::read_text(path)?;
        Self::parse(&text, Some(path))
    }

    /// Parses and checks a study description (`path` only locates errors).
    pub fn parse(text: &str, path: Option<&Path>) -> Result<Self, ConfigError> {
        let origin = Origin {
            path: path.map(Path::to_owned),
            text: Some(text.to_owned()),
        };
        let parse_error = |message: String| ConfigError::Parse {
            path: path.unwrap_or(Path::new("<study>")).to_owned(),
            message,
        };
        let mut tree: toml::Table =
            toml::from_str(text).map_err(|e| parse_error(servo_config::toml_message(text, &e)))?;
        let study = tree
            .remove("study")
            .ok_or_else(|| origin.invalid("study", "missing", "a [study] table"))?;
        let table: StudyTable = study
            .try_into()
            .map_err(|e: toml::de::Error| parse_error(format!("[study]: {e}")))?;
        let base_config: RunConfig = toml::Value::Table(tree)
            .try_into()
            .map_err(|e: toml::de::Error| parse_error(e.to_string()))?;
        base_config.validate(&origin)?;
        let base = toml::Value::try_from(&base_config).expect("configurations serialise");
        let study = Study {
            table,
            base,
            base_config,
            origin,
            text: text.to_owned(),
            sha256: sha256_hex(text.as_bytes()),
        };
        study.check()?;
        Ok(study)
    }

    fn check(&self) -> Result<(), ConfigError> {
        let t = &self.table;
        let o = &self.origin;
        if t.controllers.is_empty() {
            return Err(o.invalid(
                "study.controllers",
                "[]",
                "one or more of h2, h2-bandwidth, pid",
            ));
        }
        if !(t.bandwidth_hz > 0.0
            && t.bandwidth_hz < 0.25 * self.base_config.plant.timing.servo_rate_hz)
        {
            return Err(o.invalid(
                "study.bandwidth_hz",
                t.bandwidth_hz,
                "0 < f < servo rate / 4 Hz",
            ));
        }
        if !(t.effort_weight_nm_per_v > 0.0 && t.effort_weight_nm_per_v.is_finite()) {
            return Err(o.invalid(
                "study.effort_weight_nm_per_v",
                t.effort_weight_nm_per_v,
                "> 0 nm/V",
            ));
        }
        for (key, v) in [("study.pid_ms", t.pid_ms), ("study.pid_mt", t.pid_mt)] {
            if !(v > 1.0 && v < 10.0) {
                return Err(o.invalid(key, v, "1 < M < 10"));
            }
        }
        if t.parameters.len() > MAX_PARAMETERS {
            return Err(o.invalid(
                "study.parameter",
                t.parameters.len(),
                &format!("at most {MAX_PARAMETERS} parameters"),
            ));
        }
        match t.sampling {
            Sampling::Grid if t.samples != 0 => {
                return Err(o.invalid("study.samples", t.samples, "0 with grid sampling (the grid's points are each parameter's `points` or `values`)"));
            }
            Sampling::Random | Sampling::LatinHypercube
                if !(1..=MAX_POINTS).contains(&t.samples) =>
            {
                return Err(o.invalid("study.samples", t.samples, &format!("1..={MAX_POINTS}")));
            }
            _ => {}
        }
        for (i, p) in t.parameters.iter().enumerate() {
            self.check_parameter(i, p)?;
        }
        let points = self
            .points_per_family()
            .checked_mul(t.controllers.len() as u64);
        match points {
            Some(n) if n <= MAX_POINTS => Ok(()),
            _ => Err(o.invalid(
                "study",
                format!(
                    "{} points",
                    points.map_or("more than 2^64".into(), |n| n.to_string())
                ),
                &format!("at most {MAX_POINTS} points in all (families × samples or grid points)"),
            )),
        }
    }

    fn check_parameter(&self, i: usize, p: &Parameter) -> Result<(), ConfigError> {
        let o = &self.origin;
        let at = |field: &str| format!("study.parameter[{i}].{field}");
        if p.key != MOVING_MASS_KEY && self.base_number(&p.key).is_none() {
            return Err(o.invalid(&at("key"), &p.key, &format!("a numeric key of `servo config --dump` (e.g. plant.stage.k2_n_per_m) or {MOVING_MASS_KEY}")));
        }
        if self.table.parameters[..i].iter().any(|q| q.key == p.key) {
            return Err(o.invalid(&at("key"), &p.key, "each key once"));
        }
        match (&p.values, p.from, p.to) {
            (Some(v), None, None) => {
                if v.is_empty() || v.len() as u64 > MAX_POINTS || v.iter().any(|x| !x.is_finite()) {
                    return Err(o.invalid(
                        &at("values"),
                        format!("{} values", v.len()),
                        "1 or more finite numbers",
                    ));
                }
                if p.points.is_some() {
                    return Err(o.invalid(
                        &at("points"),
                        p.points.unwrap_or(0),
                        "absent with `values`",
                    ));
                }
            }
            (None, Some(a), Some(b)) => {
                let log = p.spacing == Spacing::Log;
                if !(a.is_finite() && b.is_finite()) || (log && !(a > 0.0 && b > 0.0)) {
                    return Err(o.invalid(
                        &at("from"),
                        format!("{a} … {b}"),
                        if log {
                            "finite and > 0 with log spacing"
                        } else {
                            "finite numbers"
                        },
                    ));
                }
                let grid = self.table.sampling == Sampling::Grid;
                match p.points {
                    Some(n) if grid && (1..=MAX_POINTS).contains(&n) => {}
                    None if !grid => {}
                    other => {
                        let range = if grid {
                            format!("1..={MAX_POINTS} with grid sampling")
                        } else {
                            "absent with random or Latin-hypercube sampling (study.samples sets the points)".into()
                        };
                        return Err(o.invalid(
                            &at("points"),
                            other.map_or("absent".into(), |n| n.to_string()),
                            &range,
                        ));
                    }
                }
            }
            _ => {
                return Err(o.invalid(
                    &at("values"),
                    "",
                    "either `values = [...]` or both `from` and `to`",
                ))
            }
        }
        Ok(())
    }

    /// The value at dotted `key` of the operating point.
    pub fn base_value(&self, key: &str) -> Option<&toml::Value> {
        key.split('.').try_fold(&self.base, |v, part| v.get(part))
    }

    /// The number at dotted `key` of the operating point, if the key names a number.
    pub fn base_number(&self, key: &str) -> Option<f64> {
        match self.base_value(key)? {
            toml::Value::Float(x) => Some(*x),
            toml::Value::Integer(i) => Some(*i as f64),
            _ => None,
        }
    }

    /// The operating point's value of parameter `p` (the moving mass is m1 + m2).
    pub fn operating_value(&self, p: &Parameter) -> f64 {
        if p.key == MOVING_MASS_KEY {
            let s = &self.base_config.plant.stage;
            return s.m1_kg + s.m2_kg;
        }
        self.base_number(&p.key).unwrap_or(f64::NAN)
    }

    /// Points per controller family.
    pub fn points_per_family(&self) -> u64 {
        match self.table.sampling {
            Sampling::Grid => self
                .table
                .parameters
                .iter()
                .try_fold(1u64, |n, p| n.checked_mul(p.grid_len()))
                .unwrap_or(u64::MAX),
            _ => self.table.samples,
        }
    }

    /// Points in the whole study (families × points per family).
    pub fn points(&self) -> u64 {
        self.points_per_family() * self.table.controllers.len() as u64
    }
}

impl Parameter {
    /// Values on the grid.
    pub fn grid_len(&self) -> u64 {
        match &self.values {
            Some(v) => v.len() as u64,
            None => self.points.unwrap_or(1),
        }
    }
}
