//! Property tests: outputs stay within limits for arbitrary finite inputs; a non-finite input
//! gives output 0 and a latched fault, cleared by `reset`.

use crate::common;

use common::*;
use proptest::prelude::*;
use servo_core::*;

fn finite() -> impl Strategy<Value = f64> {
    prop_oneof![
        -1e3..1e3f64,
        -1e12..1e12f64,
        Just(0.0),
        Just(f64::MAX),
        Just(-f64::MAX)
    ]
}

fn non_finite() -> impl Strategy<Value = f64> {
    prop_oneof![Just(f64::NAN), Just(f64::INFINITY), Just(f64::NEG_INFINITY)]
}

fn within(u: f64) -> bool {
    u >= LIMITS.min() && u <= LIMITS.max()
}

/// Runs `block` on `inputs`, checking every output is finite and within `LIMITS` or that the
/// block reported a fault and output exactly 0.
fn check_limited<B: Block<Output = f64>>(mut block: B, inputs: impl Iterator<Item = B::Input>) {
    for x in inputs {
        let u = block.update(x);
        if block.faulted() {
            assert_eq!(u, 0.0);
        } else {
            assert!(within(u), "output {u} outside limits");
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn limited_blocks_respect_limits(xs in prop::collection::vec((finite(), finite()), 1..200)) {
        check_limited(pid(), xs.iter().map(|p| p.0));
        check_limited(cascade(), xs.iter().map(|p| CascadeInput { error: p.0, accel: p.1 }));
        check_limited(observer(), xs.iter().map(|p| ObserverInput { control: p.0, inner: p.1 }));
        check_limited(feedforward(), xs.iter().map(|p| Setpoint { position: p.0, velocity: p.1, acceleration: p.0 }));
        let mut ss = state_space_27();
        for p in &xs {
            let [u] = ss.update([p.0]);
            let ok = if ss.faulted() { u == 0.0 } else { within(u) };
            prop_assert!(ok, "state-space output {} outside limits", u);
        }
    }

    #[test]
    fn non_finite_input_zeroes_output_and_latches(
        before in prop::collection::vec(-1.0..1.0f64, 0..20),
        bad in non_finite(),
        after in prop::collection::vec(-1.0..1.0f64, 1..20),
    ) {
        fn run<B: Block<Output = f64>>(mut b: B, before: &[f64], bad: f64, after: &[f64], wrap: impl Fn(f64) -> B::Input) {
            for &x in before {
                b.update(wrap(x));
            }
            assert_eq!(b.update(wrap(bad)), 0.0, "{}", core::any::type_name::<B>());
            assert!(b.faulted());
            for &x in after {
                assert_eq!(b.update(wrap(x)), 0.0, "fault stays latched");
            }
            b.reset();
            assert!(!b.faulted());
            b.update(wrap(after[0]));
            assert!(!b.faulted());
        }
        run(pid(), &before, bad, &after, |x| x);
        run(biquad(), &before, bad, &after, |x| x);
        run(delay(), &before, bad, &after, |x| x);
        run(cascade(), &before, bad, &after, |x| CascadeInput { error: x, accel: x });
        run(cascade(), &before, bad, &after, |x| CascadeInput { error: 0.0, accel: x });
        run(observer(), &before, bad, &after, |x| ObserverInput { control: x, inner: x });
        run(feedforward(), &before, bad, &after, |x| Setpoint { position: x, ..Setpoint::ZERO });
        run(Averager::<4>::new(), &before, bad, &after, |x| [x, 0.0, 0.0, 0.0]);
        let mut ss = state_space_27();
        for &x in &before { ss.update([x]); }
        prop_assert_eq!(ss.update([bad]), [0.0]);
        prop_assert!(ss.faulted());
    }
}
