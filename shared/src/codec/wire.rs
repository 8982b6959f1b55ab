//! Little-endian field readers and writers over fixed buffers, for the message
//! payloads and the flash records: every access is bounds-checked and reports
//! running out of room instead of panicking. [`Field`] is a value with a fixed
//! layout, read and written whole.

/// Reads little-endian fields from a slice, front to back.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Reader<'a> {
    /// The bytes not yet read.
    rest: &'a [u8],
}

impl<'a> Reader<'a> {
    /// A reader at the start of `bytes`.
    pub(crate) fn new(bytes: &'a [u8]) -> Self {
        Reader { rest: bytes }
    }

    /// The next `N` bytes, or `None` (and nothing consumed) if fewer are left.
    pub(crate) fn array<const N: usize>(&mut self) -> Option<[u8; N]> {
        let (head, tail) = self.rest.split_first_chunk::<N>()?;
        self.rest = tail;
        Some(*head)
    }

    /// The next byte.
    pub(crate) fn u8(&mut self) -> Option<u8> {
        self.array::<1>().map(|[b]| b)
    }

    /// The next `u16`, little-endian.
    pub(crate) fn u16(&mut self) -> Option<u16> {
        self.array().map(u16::from_le_bytes)
    }

    /// The next `u32`, little-endian.
    pub(crate) fn u32(&mut self) -> Option<u32> {
        self.array().map(u32::from_le_bytes)
    }

    /// The next `f32`, IEEE 754 binary32, little-endian (any bit pattern, NaN too).
    pub(crate) fn f32(&mut self) -> Option<f32> {
        self.array().map(f32::from_le_bytes)
    }

    /// `n` zero bytes (reserved fields): `None` if fewer are left or one is not 0.
    pub(crate) fn zeros(&mut self, n: usize) -> Option<()> {
        let (head, tail) = self.rest.split_at_checked(n)?;
        self.rest = tail;
        head.iter().all(|&b| b == 0).then_some(())
    }

    /// Whether every byte has been read.
    pub(crate) fn is_empty(&self) -> bool {
        self.rest.is_empty()
    }
}

/// Writes little-endian fields into a slice, front to back; a write that does not
/// fit sets a flag and writes nothing.
#[derive(Debug)]
pub(crate) struct Writer<'a> {
    /// The whole output buffer.
    buf: &'a mut [u8],
    /// Bytes written so far.
    len: usize,
    /// A write did not fit.
    overflow: bool,
}

impl<'a> Writer<'a> {
    /// A writer at the start of `buf`.
    pub(crate) fn new(buf: &'a mut [u8]) -> Self {
        Writer {
            buf,
            len: 0,
            overflow: false,
        }
    }

    /// Append `bytes`, or flag an overflow.
    pub(crate) fn bytes(&mut self, bytes: &[u8]) {
        let end = self.len.saturating_add(bytes.len());
        match self.buf.get_mut(self.len..end) {
            Some(dst) if !self.overflow => {
                dst.copy_from_slice(bytes);
                self.len = end;
            }
            _ => self.overflow = true,
        }
    }

    /// Append a byte.
    pub(crate) fn u8(&mut self, v: u8) {
        self.bytes(&[v]);
    }

    /// Append a `u16`, little-endian.
    pub(crate) fn u16(&mut self, v: u16) {
        self.bytes(&v.to_le_bytes());
    }

    /// Append a `u32`, little-endian.
    pub(crate) fn u32(&mut self, v: u32) {
        self.bytes(&v.to_le_bytes());
    }

    /// Append an `f32`, little-endian.
    pub(crate) fn f32(&mut self, v: f32) {
        self.bytes(&v.to_le_bytes());
    }

    /// Append `n` zero bytes (reserved fields).
    pub(crate) fn zeros(&mut self, n: usize) {
        for _ in 0..n {
            self.u8(0);
        }
    }

    /// The number of bytes written, or `None` if a write did not fit.
    pub(crate) fn finish(self) -> Option<usize> {
        (!self.overflow).then_some(self.len)
    }
}

/// A flag byte: `bit` set for every `(set, bit)` whose `set` is true.
pub(crate) fn flag_byte(flags: &[(bool, u8)]) -> u8 {
    flags
        .iter()
        .filter(|(set, _)| *set)
        .fold(0, |byte, (_, bit)| byte | bit)
}

/// A value with a fixed little-endian layout, the same in a message payload and in
/// the flash record (its length is a constant beside its implementation).
pub(crate) trait Field: Sized {
    /// Append the layout's bytes.
    fn write(&self, w: &mut Writer<'_>);

    /// Read the layout's bytes; `None` if too few are left, or a value is outside
    /// the layout's domain (an unknown flag, a reserved byte not zero).
    fn read(r: &mut Reader<'_>) -> Option<Self>;
}
