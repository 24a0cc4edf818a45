//! The parameter values of each point, computed from the study and the point's index alone
//! (no state carried between points): any worker, shard or Ray task gets the same values for
//! the same index. Random and Latin-hypercube draws come from a counter-based generator
//! (SplitMix64 of the seed, index and parameter) and the Latin-hypercube strata from a keyed
//! Feistel permutation of the sample indices (cycle-walked into range).

use super::spec::{Parameter, Sampling, Spacing, Study};

/// SplitMix64's finaliser: a bijective 64-bit mix.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A uniform number in [0, 1) for (seed, sample, parameter, stream).
fn uniform(seed: u64, sample: u64, parameter: usize, stream: u64) -> f64 {
    let h = mix(mix(mix(seed ^ stream.rotate_left(48)) ^ sample) ^ parameter as u64);
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// A keyed permutation of `0..n` (a 4-round Feistel network on the smallest even bit width
/// that holds `n`, cycle-walked: outputs ≥ n are permuted again until they fall in range).
fn permute(i: u64, n: u64, key: u64) -> u64 {
    let bits = (64 - n.saturating_sub(1).leading_zeros()).max(2);
    let half = bits.div_ceil(2);
    let mask = (1u64 << half) - 1;
    let mut x = i;
    loop {
        let (mut l, mut r) = (x >> half, x & mask);
        for round in 0..4u64 {
            let f = mix(key ^ round.wrapping_mul(0x5851_f42d_4c95_7f2d) ^ r) & mask;
            (l, r) = (r, l ^ f);
        }
        x = (l << half) | r;
        if x < n {
            return x;
        }
    }
}

/// `u` in [0, 1] mapped onto the parameter's range or value list.
fn place(p: &Parameter, u: f64) -> f64 {
    if let Some(v) = &p.values {
        let i = ((u * v.len() as f64) as usize).min(v.len() - 1);
        return v[i];
    }
    let (a, b) = (p.from.unwrap_or(0.0), p.to.unwrap_or(0.0));
    match p.spacing {
        Spacing::Linear => a + (b - a) * u,
        Spacing::Log => libm::exp(libm::log(a) + (libm::log(b) - libm::log(a)) * u),
    }
}

/// The `i`-th of a parameter's grid values.
fn grid_value(p: &Parameter, i: u64) -> f64 {
    if let Some(v) = &p.values {
        return v[i as usize];
    }
    let n = p.points.unwrap_or(1);
    if n <= 1 || i == 0 {
        return p.from.unwrap_or(0.0);
    }
    if i == n - 1 {
        return p.to.unwrap_or(0.0);
    }
    place(p, i as f64 / (n - 1) as f64)
}

/// The parameter values of sample `sample` (within one controller family), in parameter order.
pub fn values(study: &Study, sample: u64) -> Vec<f64> {
    let t = &study.table;
    let n = t.samples;
    match t.sampling {
        Sampling::Grid => {
            let mut rest = sample;
            let mut out = vec![0.0; t.parameters.len()];
            for (j, p) in t.parameters.iter().enumerate().rev() {
                let len = p.grid_len();
                out[j] = grid_value(p, rest % len);
                rest /= len;
            }
            out
        }
        Sampling::Random => t
            .parameters
            .iter()
            .enumerate()
            .map(|(j, p)| place(p, uniform(t.seed, sample, j, 0)))
            .collect(),
        Sampling::LatinHypercube => t
            .parameters
            .iter()
            .enumerate()
            .map(|(j, p)| {
                let stratum = permute(sample, n, mix(t.seed ^ mix(j as u64 + 1)));
                let u = (stratum as f64 + uniform(t.seed, sample, j, 1)) / n as f64;
                place(p, u)
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_feistel_permutation_is_a_permutation() {
        for n in [1u64, 2, 3, 7, 64, 100, 1000, 4097] {
            let mut seen = vec![false; n as usize];
            for i in 0..n {
                let p = permute(i, n, 0xdead_beef ^ n) as usize;
                assert!(!seen[p], "n = {n}: {p} twice");
                seen[p] = true;
            }
        }
    }

    #[test]
    fn latin_hypercube_uses_every_stratum_of_every_parameter_once() {
        let text = "[study]\nsampling = \"latin-hypercube\"\nsamples = 50\nseed = 7\n\
                    [[study.parameter]]\nkey = \"plant.stage.k2_n_per_m\"\nfrom = 1e4\nto = 1e6\nspacing = \"log\"\n\
                    [[study.parameter]]\nkey = \"plant.stage.c2_n_s_per_m\"\nfrom = 0.0\nto = 100.0\n";
        let study = Study::parse(text, None).unwrap();
        let mut strata = [vec![0u32; 50], vec![0u32; 50]];
        for k in 0..50 {
            let v = values(&study, k);
            let u0 = libm::log(v[0] / 1e4) / libm::log(100f64);
            let u1 = v[1] / 100.0;
            strata[0][(u0 * 50.0) as usize] += 1;
            strata[1][(u1 * 50.0) as usize] += 1;
        }
        assert!(
            strata.iter().all(|s| s.iter().all(|&c| c == 1)),
            "{strata:?}"
        );
    }

    #[test]
    fn grid_enumerates_the_last_parameter_fastest_with_exact_ends() {
        let text = "[study]\n[[study.parameter]]\nkey = \"plant.stage.k2_n_per_m\"\nfrom = 1e3\nto = 1e5\npoints = 3\nspacing = \"log\"\n\
                    [[study.parameter]]\nkey = \"plant.stage.c2_n_s_per_m\"\nvalues = [1.0, 2.0]\n";
        let study = Study::parse(text, None).unwrap();
        assert_eq!(study.points(), 6);
        let all: Vec<Vec<f64>> = (0..6).map(|k| values(&study, k)).collect();
        assert_eq!(all[0], vec![1e3, 1.0]);
        assert_eq!(all[1], vec![1e3, 2.0]);
        assert!((all[2][0] - 1e4).abs() < 1e-9);
        assert_eq!(all[5], vec![1e5, 2.0]);
    }
}
