//! The MCAP format's constants and its record encoding (<https://mcap.dev/spec>,
//! little-endian throughout): what the writer ([`crate::mcap_file`]) puts down and the readers
//! look for.

/// MCAP magic bytes, at the start and end of a file.
pub const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

/// The header's `library` of the files written here: every byte is covered by a CRC (the data
/// section's in the Data End record, the summary's in the footer, each chunk's and
/// attachment's), so a reader treats a zero CRC in such a file as damage.
pub const LIBRARY: &str = "fts-servo recorder 2 (every byte CRC-checked)";

/// Record opcodes (MCAP specification).
pub mod op {
    /// Header.
    pub const HEADER: u8 = 0x01;
    /// Footer.
    pub const FOOTER: u8 = 0x02;
    /// Schema.
    pub const SCHEMA: u8 = 0x03;
    /// Channel.
    pub const CHANNEL: u8 = 0x04;
    /// Message.
    pub const MESSAGE: u8 = 0x05;
    /// Chunk.
    pub const CHUNK: u8 = 0x06;
    /// Message index.
    pub const MESSAGE_INDEX: u8 = 0x07;
    /// Chunk index.
    pub const CHUNK_INDEX: u8 = 0x08;
    /// Attachment.
    pub const ATTACHMENT: u8 = 0x09;
    /// Attachment index.
    pub const ATTACHMENT_INDEX: u8 = 0x0A;
    /// Statistics.
    pub const STATISTICS: u8 = 0x0B;
    /// Metadata.
    pub const METADATA: u8 = 0x0C;
    /// Metadata index.
    pub const METADATA_INDEX: u8 = 0x0D;
    /// Summary offset.
    pub const SUMMARY_OFFSET: u8 = 0x0E;
    /// Data end.
    pub const DATA_END: u8 = 0x0F;
}

/// Little-endian field encoding into a byte buffer.
pub(crate) trait Put {
    fn u8(&mut self, v: u8) -> &mut Self;
    fn u16(&mut self, v: u16) -> &mut Self;
    fn u32(&mut self, v: u32) -> &mut Self;
    fn u64(&mut self, v: u64) -> &mut Self;
    /// `uint32` length prefix, then the UTF-8 bytes.
    fn str(&mut self, s: &str) -> &mut Self;
    /// A length-prefixed group whose byte length is known only after it is written
    /// (`uint32` for arrays and maps).
    fn group32(&mut self, body: impl FnOnce(&mut Vec<u8>)) -> &mut Self;
}

impl Put for Vec<u8> {
    fn u8(&mut self, v: u8) -> &mut Self {
        self.push(v);
        self
    }
    fn u16(&mut self, v: u16) -> &mut Self {
        self.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn u32(&mut self, v: u32) -> &mut Self {
        self.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn u64(&mut self, v: u64) -> &mut Self {
        self.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn str(&mut self, s: &str) -> &mut Self {
        self.u32(s.len() as u32);
        self.extend_from_slice(s.as_bytes());
        self
    }
    fn group32(&mut self, body: impl FnOnce(&mut Vec<u8>)) -> &mut Self {
        let at = self.len();
        self.u32(0);
        body(self);
        let len = (self.len() - at - 4) as u32;
        self[at..at + 4].copy_from_slice(&len.to_le_bytes());
        self
    }
}

/// Appends one record: opcode, `uint64` length, body.
pub(crate) fn record(out: &mut Vec<u8>, opcode: u8, body: impl FnOnce(&mut Vec<u8>)) {
    out.u8(opcode).u64(0);
    let at = out.len();
    body(out);
    let len = (out.len() - at) as u64;
    out[at - 8..at].copy_from_slice(&len.to_le_bytes());
}
