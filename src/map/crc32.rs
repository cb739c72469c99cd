//! CRC-32 (ISO-HDLC: reflected 0x04C11DB7, init and final XOR 0xFFFFFFFF),
//! the zlib/PNG checksum. A 1 KiB table built at compile time.

const TABLE: [u32; 256] = {
    let mut t = [0u32; 256];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
            k += 1;
        }
        #[allow(
            clippy::indexing_slicing,
            reason = "evaluated at compile time: an index past the end is a build error, not a panic"
        )]
        {
            t[i] = c;
        }
        i += 1;
    }
    t
};

/// The CRC-32 of `data`.
///
/// ```
/// assert_eq!(echoloc::map::crc32(b"123456789"), 0xCBF4_3926);
/// ```
pub fn crc32(data: &[u8]) -> u32 {
    let mut c = Crc32::new();
    c.update(data);
    c.finish()
}

/// A CRC-32 over data that arrives in parts (a file written record by record).
///
/// ```
/// let mut c = echoloc::map::Crc32::new();
/// c.update(b"1234");
/// c.update(b"56789");
/// assert_eq!(c.finish(), echoloc::map::crc32(b"123456789"));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Crc32(u32);

impl Crc32 {
    /// Nothing seen yet.
    pub const fn new() -> Self {
        Self(!0)
    }
    /// Takes in `data`.
    pub fn update(&mut self, data: &[u8]) {
        // `get` on a u8 index of a 256-entry table: never None, and no panic path.
        self.0 = data.iter().fold(self.0, |c, &b| TABLE.get(usize::from(b ^ c as u8)).copied().unwrap_or(0) ^ (c >> 8));
    }
    /// The CRC of everything taken in.
    pub const fn finish(self) -> u32 {
        !self.0
    }
}

impl Default for Crc32 {
    fn default() -> Self {
        Self::new()
    }
}
