//! The averaged ADC rounding error the budget assumes (`plant_sim::quantisation`) against a
//! Monte Carlo of the simulator's own quantiser on the simulator's own sensor noise: the
//! 16-bit ±4.096 V ADC converting four times per tick at 1 MHz (thesis §4.5.2) with the
//! calibrated sensor noise (≈ 1 LSB RMS, band-limited at 15 kHz), at 199.6 and 20 kHz.

use plant_sim::convert::Quantizer;
use plant_sim::params::PlantParams;
use plant_sim::quantisation::{averaged_rounding_error, ConversionGrid};
use plant_sim::sampled_noise::SampledNoise;
use plant_sim::sensor_noise::SensorNoise;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rand_xoshiro::Xoshiro256PlusPlus;

/// Ticks per Monte Carlo run and the batches its scatter is estimated from.
const TICKS: usize = 1 << 21;
const BATCHES: usize = 64;

/// Autocovariance of `s` at lags 0 and 1 (its impulse response against the innovations).
fn model_lags(s: &SampledNoise) -> [f64; 2] {
    let (a, k, c) = (&s.sys.a, &s.sys.b, &s.sys.c);
    if s.states() == 0 {
        return [s.variance, 0.0];
    }
    let (p, _) = lti::dlyap(a, &(k * k.transpose() * s.variance)).unwrap();
    let r1 = (c * (a * &p * c.transpose() + k * s.variance))[(0, 0)];
    [s.total_variance(), r1]
}

/// Per batch, the variance and lag-1 covariance of the averaged rounding error.
fn monte_carlo(noise: &mut SensorNoise, adc: &Quantizer, seed: u64) -> Vec<[f64; 2]> {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    // A fixed gap voltage off any code centre: the noise alone dithers the converter.
    let offset = 0.37 * adc.lsb_v() + 1.25;
    let per = TICKS / BATCHES;
    let mut out = Vec::with_capacity(BATCHES);
    let mut last = 0.0;
    for _ in 0..BATCHES {
        let (mut s0, mut s1) = (0.0, 0.0);
        for _ in 0..per {
            let mut e = 0.0;
            for c in 0..4 {
                let x = offset + noise.next(c == 0, || StandardNormal.sample(&mut rng));
                e += adc.convert(x).0 - x;
            }
            e /= 4.0;
            s0 += e * e;
            s1 += e * last;
            last = e;
        }
        out.push([s0 / per as f64, s1 / per as f64]);
    }
    out
}

/// Mean and standard error of the batch values.
fn mean_and_error(x: impl Iterator<Item = f64> + Clone) -> (f64, f64) {
    let n = x.clone().count() as f64;
    let mean = x.clone().sum::<f64>() / n;
    let var = x.map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

#[test]
fn the_averaged_rounding_error_is_the_monte_carlos() {
    let p = PlantParams::heavy();
    let adc = Quantizer::new(p.adc.bits, p.adc.range_v);
    let lsb = adc.lsb_v();
    for rate in [199.6e3, 20e3] {
        let grid = ConversionGrid {
            period_s: 1.0 / rate,
            oversampling: p.adc.oversampling,
            conversion_rate_hz: p.adc.conversion_rate_hz,
        };
        let mut noise = SensorNoise::new(
            p.noise.sensor_v_per_rt_hz,
            p.capa.bandwidth_hz,
            p.adc.anti_alias_hz,
            grid.period_s,
            grid.oversampling,
            grid.conversion_rate_hz,
        );
        let model = averaged_rounding_error(lsb, Some(&noise), &grid).unwrap();
        let [r0, r1] = model_lags(&model);
        let batches = monte_carlo(&mut noise, &adc, 11);
        let (v, v_err) = mean_and_error(batches.iter().map(|b| b[0]));
        let (c1, c1_err) = mean_and_error(batches.iter().map(|b| b[1]));
        let independent = lsb * lsb / 12.0 / 4.0;
        println!(
            "{:.1} kHz: noise {:.2} LSB RMS; variance model {:.4} MC {:.4} ± {:.4}, lag 1 model {:.4} MC {:.4} ± {:.4} (in LSB²/48, the independent conversions' variance)",
            rate / 1e3,
            noise.conversion_variance().sqrt() / lsb,
            r0 / independent,
            v / independent,
            v_err / independent,
            r1 / independent,
            c1 / independent,
            c1_err / independent,
        );
        // The Monte Carlo is precise enough to judge a 2 % model (three standard errors
        // inside it), and the model is within three of its standard errors.
        assert!(3.0 * v_err < 0.02 * r0, "scatter {v_err} of {r0}");
        assert!((v - r0).abs() < 3.0 * v_err, "variance {v} vs model {r0}");
        assert!((c1 - r1).abs() < 3.0 * c1_err, "lag 1 {c1} vs {r1}");
        // Independent conversions would be far off: the tick keeps most of the error.
        assert!(r0 > 2.0 * independent);
    }
}
