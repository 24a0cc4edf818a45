//! Little-endian fields of an MCAP record body (MCAP specification), each read failing with
//! what was missing rather than panicking.

use std::collections::BTreeMap;

/// Little-endian fields of a record body, each failing with what was missing.
pub(crate) struct Fields<'a>(pub(crate) &'a [u8]);

impl<'a> Fields<'a> {
    pub(crate) fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
    pub(crate) fn u8(&mut self) -> Result<u8, String> {
        Ok(self.bytes(1)?[0])
    }
    pub(crate) fn bytes(&mut self, n: usize) -> Result<&'a [u8], String> {
        if self.0.len() < n {
            return Err("record too short".into());
        }
        let (head, rest) = self.0.split_at(n);
        self.0 = rest;
        Ok(head)
    }
    pub(crate) fn u16(&mut self) -> Result<u16, String> {
        Ok(u16::from_le_bytes(self.bytes(2)?.try_into().expect("2")))
    }
    pub(crate) fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.bytes(4)?.try_into().expect("4")))
    }
    pub(crate) fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.bytes(8)?.try_into().expect("8")))
    }
    pub(crate) fn str(&mut self) -> Result<String, String> {
        let n = self.u32()? as usize;
        String::from_utf8(self.bytes(n)?.to_vec()).map_err(|_| "string not UTF-8".into())
    }
    pub(crate) fn string_map(&mut self) -> Result<BTreeMap<String, String>, String> {
        let n = self.u32()? as usize;
        let mut m = Fields(self.bytes(n)?);
        let mut map = BTreeMap::new();
        while !m.0.is_empty() {
            map.insert(m.str()?, m.str()?);
        }
        Ok(map)
    }
}
