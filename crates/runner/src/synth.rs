//! H2-optimal controller design on the simulator's exact discrete model (thesis Ch. 6, in the
//! spirit of Fig 6-3 but with the plant the simulator runs): the noise shaping filters are
//! already in the model, so the controller directly minimises the variance of the **true** tool
//! position (z1, in nm) plus `ρ²·u²` (z2), given the sensor, current, base and converter noise.
//! The transport delay, the hold and the ADC averaging are in the tick, so the design knows
//! them (DESIGN.md, "Discrete controllers are designed knowing this delay").

use crate::config::Loaded;
use crate::run::{plant_error, RunError};
use design::h2::{h2syn_discrete, GeneralizedPlant};
use design::lti::StateSpace;
use nalgebra::DMatrix;
use plant_sim::Simulator;

/// The designed controller in the form `servo run --controller ss` loads (input: position
/// error `r − gap` in sensor volts, output: command in V) and what the design predicts.
#[derive(Debug, Clone)]
pub struct Design {
    /// The controller, sampled at `sample_rate_hz`.
    pub controller: StateSpace,
    /// Its sample rate in Hz (the run's servo rate).
    pub sample_rate_hz: f64,
    /// Closed-loop H2 norm of the design problem (nm and weighted V, per-sample white inputs).
    pub h2_norm: f64,
    /// Closed-loop spectral radius of the design model.
    pub spectral_radius: f64,
}

impl Design {
    /// The controller file (TOML) for `servo run --controller ss --ss-file`.
    pub fn to_toml(&self) -> String {
        let rows = |m: &DMatrix<f64>| {
            let r: Vec<String> = (0..m.nrows())
                .map(|i| {
                    format!(
                        "[{}]",
                        (0..m.ncols())
                            .map(|j| format!("{:e}", m[(i, j)]))
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                })
                .collect();
            format!("[\n  {},\n]", r.join(",\n  "))
        };
        let k = &self.controller;
        format!(
            "# H2-optimal controller designed by `servo synth h2` on the simulator's exact model.\n\
             # x⁺ = A x + B e, u = C x + D e; e = reference − measurement in sensor volts, u in V.\n\
             # {} states; design closed-loop H2 norm {:.6e}, spectral radius {:.6}.\n\
             sample_rate_hz = {}\na = {}\nb = {}\nc = {}\nd = {}\n",
            k.nx(),
            self.h2_norm,
            self.spectral_radius,
            self.sample_rate_hz,
            rows(&k.a),
            rows(&k.b),
            rows(&k.c),
            rows(&k.d)
        )
    }
}

impl Design {
    /// The same controller reduced to `order` states by balanced truncation (thesis Table 6-1
    /// sizes: 8, 13, full); returns the Hankel singular values and the H∞ error bound too.
    /// The controller itself must be stable.
    pub fn reduced(&self, order: usize) -> Result<(Design, Vec<f64>, f64), RunError> {
        let r = design::reduce::balanced_truncation(&self.controller, order)
            .map_err(|e| RunError::Plant(format!("reduction needs a stable controller: {e}")))?;
        let mut d = self.clone();
        d.controller = r.sys;
        Ok((d, r.hankel, r.error_bound))
    }
}

/// Designs the H2 controller for the plant of `cfg` at its servo rate; `effort_nm_per_v` is ρ,
/// the weight of one volt of command against one nanometre of tool error.
pub fn h2_design(cfg: &Loaded, effort_nm_per_v: f64) -> Result<Design, RunError> {
    let c = &cfg.config;
    c.validate(cfg)?;
    let sim = Simulator::new(&c.plant, 0, &Default::default()).map_err(|e| plant_error(e, cfg))?;
    let t = sim
        .linear_tick()
        .ok_or_else(|| RunError::Plant("H2 design needs the ideal current-loop model".into()))?;
    let n = t.phi.nrows();
    let (iu, iy, size) = (n, n + 1, n + 2);
    let sigma_w = t.white_variance.map(f64::sqrt);
    let sigma_s = t.sensor_noise_variance.sqrt();
    // Measurement noise on the reading: the ADC's quantisation (a floor keeps D21 full rank for
    // an ideal converter).
    let sigma_q = t
        .adc_quantisation_variance
        .sqrt()
        .max(1e-3 * sigma_s)
        .max(1e-12);
    // w = [sensor, current, base, accelerometer, quantisation], unit variance per tick.
    let nw = 5;
    let mut a = DMatrix::zeros(size, size);
    let mut b1 = DMatrix::zeros(size, nw);
    let mut b2 = DMatrix::zeros(size, 1);
    a.view_mut((0, 0), (n, n)).copy_from(&t.phi);
    a.view_mut((0, iu), (n, 1)).copy_from(&t.g.column(0));
    b2.view_mut((0, 0), (n, 1)).copy_from(&t.g.column(1));
    b2[(iu, 0)] = 1.0;
    a.view_mut((iy, 0), (1, n)).copy_from(&t.y_x.row(0));
    a[(iy, iu)] = t.y_in[(0, 0)];
    b2[(iy, 0)] = t.y_in[(0, 1)];
    b1[(iy, 0)] = sigma_s;
    for k in 0..3 {
        // plant input columns 3..6 are the current, base and accelerometer white inputs
        b1.view_mut((0, 1 + k), (n, 1))
            .copy_from(&(t.g.column(3 + k) * sigma_w[k]));
        b1[(iy, 1 + k)] = t.y_in[(0, 3 + k)] * sigma_w[k];
    }
    let mut c1 = DMatrix::zeros(2, size);
    c1.view_mut((0, 0), (1, n))
        .copy_from(&(t.t_start.row(0) * 1e9));
    let d12 = DMatrix::from_column_slice(2, 1, &[0.0, effort_nm_per_v]);
    let mut c2 = DMatrix::zeros(1, size);
    c2[(0, iy)] = 1.0;
    let mut d21 = DMatrix::zeros(1, nw);
    d21[(0, 4)] = sigma_q;
    let plant = GeneralizedPlant {
        a,
        b1,
        b2,
        c1,
        c2,
        d12,
        d21,
    };
    let k = h2syn_discrete(&plant).map_err(|e| RunError::Plant(format!("H2 synthesis: {e}")))?;
    // The runner feeds e = r − gap: with r = 0, e = −gap, so negate the input side.
    let controller = StateSpace {
        a: k.k.a.clone(),
        b: -&k.k.b,
        c: k.k.c.clone(),
        d: -&k.k.d,
    };
    Ok(Design {
        controller,
        sample_rate_hz: c.plant.timing.servo_rate_hz,
        h2_norm: k.h2_norm,
        spectral_radius: k.spectral_radius,
    })
}
