//! Whether a file is a whole 32-bit ARM executable before QEMU is given it: the ELF header,
//! then its program headers and every loadable segment within the file (a header alone, or a
//! copy cut short, is named here — QEMU would boot nothing and the link would be lost only
//! after its timeout).

use std::io::Read;
use std::path::Path;

/// Largest firmware file read, bytes.
pub const MAX_FIRMWARE_BYTES: u64 = 64 << 20;

/// ELF32's header size, bytes.
const HEADER: usize = 52;
/// A program header's type for a loadable segment.
const PT_LOAD: u32 = 1;

/// Why `path` is not a complete 32-bit little-endian ARM executable, if it is not (opened as
/// every user-named file is, [`daq_io::input_file::open_regular`], at most
/// [`MAX_FIRMWARE_BYTES`]).
pub fn check(path: &Path) -> Result<(), String> {
    let mut bytes = Vec::new();
    daq_io::input_file::open_regular(path, MAX_FIRMWARE_BYTES)
        .and_then(|(f, _)| f.take(MAX_FIRMWARE_BYTES).read_to_end(&mut bytes))
        .map_err(|e| e.to_string())?;
    check_bytes(&bytes)
}

/// [`check`] on the file's bytes.
fn check_bytes(b: &[u8]) -> Result<(), String> {
    let rebuild = "(build it: cd firmware && cargo build --release)";
    let half = |at: usize| u16::from_le_bytes([b[at], b[at + 1]]);
    let word = |at: usize| u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]);
    // ELF, 32-bit, little-endian, an executable (type 2) for machine 40 (ARM).
    if b.len() < 20
        || b[..4] != *b"\x7fELF"
        || b[4] != 1
        || b[5] != 1
        || half(16) != 2
        || half(18) != 40
    {
        return Err(format!("not a 32-bit ARM ELF {rebuild}"));
    }
    if b.len() < HEADER {
        return Err(format!(
            "truncated: {} bytes, shorter than an ELF header {rebuild}",
            b.len()
        ));
    }
    let (phoff, phentsize, phnum) = (word(28) as usize, usize::from(half(42)), half(44));
    let table_end = phoff.checked_add(phentsize * usize::from(phnum));
    if phnum == 0 || phentsize < 32 || table_end.is_none_or(|end| end > b.len()) {
        return Err(format!(
            "truncated or damaged: {phnum} program headers of {phentsize} bytes at offset {phoff}, in a file of {} bytes {rebuild}",
            b.len()
        ));
    }
    let mut loads = 0;
    for k in 0..usize::from(phnum) {
        let at = phoff + k * phentsize;
        if word(at) != PT_LOAD {
            continue;
        }
        loads += 1;
        let (offset, size) = (word(at + 4) as usize, word(at + 16) as usize);
        if offset.checked_add(size).is_none_or(|end| end > b.len()) {
            return Err(format!(
                "truncated: loadable segment {k} ({size} bytes at offset {offset}) ends beyond the file's {} bytes {rebuild}",
                b.len()
            ));
        }
    }
    if loads == 0 {
        return Err(format!("no loadable segment: nothing to run {rebuild}"));
    }
    Ok(())
}

/// A minimal ARM executable for tests: header, one program header, `body` bytes of segment.
#[cfg(test)]
pub(super) fn minimal(body: usize) -> Vec<u8> {
    let mut b = vec![0u8; HEADER + 32 + body];
    b[..6].copy_from_slice(b"\x7fELF\x01\x01");
    b[16] = 2;
    b[18] = 40;
    b[28..32].copy_from_slice(&(HEADER as u32).to_le_bytes());
    b[42] = 32;
    b[44] = 1;
    let ph = HEADER;
    b[ph..ph + 4].copy_from_slice(&PT_LOAD.to_le_bytes());
    b[ph + 4..ph + 8].copy_from_slice(&((HEADER + 32) as u32).to_le_bytes());
    b[ph + 16..ph + 20].copy_from_slice(&(body as u32).to_le_bytes());
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    fn elf(body: usize) -> Vec<u8> {
        minimal(body)
    }

    #[test]
    fn whole_executables_pass_and_cut_ones_are_named() {
        assert_eq!(check_bytes(&elf(100)), Ok(()));
        let whole = elf(100);
        for (cut, says) in [
            (40, "shorter than an ELF header"),
            (HEADER, "program headers"),
            (HEADER + 32 + 50, "loadable segment 0"),
            (10, "not a 32-bit ARM ELF"),
        ] {
            let e = check_bytes(&whole[..cut]).unwrap_err();
            assert!(e.contains(says), "{cut}: {e}");
        }
        let mut no_load = elf(0);
        no_load[HEADER] = 6;
        assert!(check_bytes(&no_load)
            .unwrap_err()
            .contains("no loadable segment"));
    }
}
