//! The recording reader on damaged files (property-based): a valid recording truncated, with
//! bytes flipped, with garbage inserted or a length field blown up, is read without a panic and
//! in bounded time — frames recovered up to the damage, or a clear error naming the file.

use crate::common;

use common::{frames, tmp, write};
use proptest::prelude::*;
use std::sync::OnceLock;

/// A valid 30 ms recording (two data chunks, overview, summary), once.
fn valid() -> &'static [u8] {
    static BYTES: OnceLock<Vec<u8>> = OnceLock::new();
    BYTES.get_or_init(|| {
        let path = tmp("fuzz-source.mcap");
        write(&path, &frames(5988));
        std::fs::read(path).unwrap()
    })
}

/// One way to damage a file.
#[derive(Debug, Clone)]
enum Damage {
    Truncate(usize),
    Flip(usize, u8),
    Insert(usize, Vec<u8>),
    /// An 8-byte little-endian length field at an offset set to a huge value.
    HugeLength(usize, u64),
}

fn damage() -> impl Strategy<Value = Damage> {
    let at = any::<prop::sample::Index>();
    prop_oneof![
        at.clone()
            .prop_map(|i| Damage::Truncate(i.index(valid().len()))),
        (at.clone(), 1u8..=255).prop_map(|(i, x)| Damage::Flip(i.index(valid().len()), x)),
        (at.clone(), prop::collection::vec(any::<u8>(), 1..64))
            .prop_map(|(i, b)| Damage::Insert(i.index(valid().len()), b)),
        (
            at,
            prop_oneof![Just(u64::MAX), Just(1u64 << 40), any::<u64>()]
        )
            .prop_map(|(i, v)| Damage::HugeLength(i.index(valid().len() - 8), v)),
    ]
}

fn apply(d: &Damage) -> Vec<u8> {
    let mut b = valid().to_vec();
    match d {
        Damage::Truncate(n) => b.truncate(*n),
        Damage::Flip(i, x) => b[*i] ^= x,
        Damage::Insert(i, bytes) => {
            b.splice(*i..*i, bytes.iter().copied());
        }
        Damage::HugeLength(i, v) => b[*i..*i + 8].copy_from_slice(&v.to_le_bytes()),
    }
    b
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1500, ..ProptestConfig::default() })]

    #[test]
    fn damaged_recordings_are_read_or_refused_never_a_panic(d in damage()) {
        let path = tmp("fuzz.mcap");
        std::fs::write(&path, apply(&d)).unwrap();
        match recorder::read(&path) {
            // What is recovered is never more than was written.
            Ok(r) => prop_assert!(r.frames.len() <= 5988, "{} frames", r.frames.len()),
            Err(e) => prop_assert!(e.to_string().contains("fuzz.mcap"), "{e}"),
        }
    }
}
