//! CDR, the encoding of ROS 2 messages on the wire: a 4-byte
//! encapsulation header (little-endian plain CDR), then each field in
//! order, every primitive aligned to its size from the end of that header;
//! strings and sequences carry a 32-bit count first (a string's counts its
//! closing NUL).

use thiserror::Error;

/// Little-endian plain CDR, as every ROS 2 middleware writes it.
const ENCAPSULATION: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// Bytes that are no message of the type they were read as.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub(crate) enum CdrError {
    #[error("the message ends before its {0}")]
    Short(&'static str),
    #[error("the encapsulation {0:02x?} is not little-endian plain CDR")]
    Encapsulation([u8; 4]),
    #[error("a string that is not UTF-8 or has no closing NUL")]
    BadString,
    #[error("{0} bytes follow the message's last field")]
    Trailing(usize),
}

/// Writes one message.
pub(crate) struct Writer {
    bytes: Vec<u8>,
}

impl Writer {
    pub(crate) fn new() -> Writer {
        Writer {
            bytes: ENCAPSULATION.to_vec(),
        }
    }

    pub(crate) fn finish(self) -> Vec<u8> {
        self.bytes
    }

    fn align(&mut self, size: usize) {
        let offset = self.bytes.len() - ENCAPSULATION.len();
        let pad = (size - offset % size) % size;
        self.bytes.extend(std::iter::repeat_n(0, pad));
    }

    pub(crate) fn i8(&mut self, v: i8) {
        self.bytes.extend(v.to_le_bytes());
    }

    pub(crate) fn bool(&mut self, v: bool) {
        self.bytes.push(u8::from(v));
    }

    pub(crate) fn i32(&mut self, v: i32) {
        self.align(4);
        self.bytes.extend(v.to_le_bytes());
    }

    pub(crate) fn u32(&mut self, v: u32) {
        self.align(4);
        self.bytes.extend(v.to_le_bytes());
    }

    pub(crate) fn f32(&mut self, v: f32) {
        self.align(4);
        self.bytes.extend(v.to_le_bytes());
    }

    pub(crate) fn f64(&mut self, v: f64) {
        self.align(8);
        self.bytes.extend(v.to_le_bytes());
    }

    /// A sequence's or string's count. Nothing the lab sends comes near
    /// 2³² elements; a count past it is cut rather than wrapped.
    pub(crate) fn count(&mut self, n: usize) {
        self.u32(u32::try_from(n).unwrap_or(u32::MAX));
    }

    pub(crate) fn string(&mut self, s: &str) {
        self.count(s.len() + 1);
        self.bytes.extend(s.as_bytes());
        self.bytes.push(0);
    }

    pub(crate) fn bytes(&mut self, b: &[u8]) {
        self.count(b.len());
        self.bytes.extend(b);
    }

    pub(crate) fn f64s(&mut self, values: &[f64]) {
        for &v in values {
            self.f64(v);
        }
    }

    pub(crate) fn f32_sequence(&mut self, values: &[f32]) {
        self.count(values.len());
        for &v in values {
            self.f32(v);
        }
    }
}

/// Reads one message; every count is checked against the bytes left, so
/// a hostile count allocates nothing.
pub(crate) struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    pub(crate) fn new(bytes: &'a [u8]) -> Result<Reader<'a>, CdrError> {
        let header: [u8; 4] = bytes
            .get(..4)
            .and_then(|h| h.try_into().ok())
            .ok_or(CdrError::Short("encapsulation"))?;
        if header != ENCAPSULATION {
            return Err(CdrError::Encapsulation(header));
        }
        Ok(Reader { bytes, at: 4 })
    }

    /// The message is over: nothing may follow but padding to 4 bytes.
    pub(crate) fn end(&self) -> Result<(), CdrError> {
        let left = self.bytes.len() - self.at;
        if left >= 4 {
            return Err(CdrError::Trailing(left));
        }
        Ok(())
    }

    fn take(&mut self, size: usize, what: &'static str) -> Result<&'a [u8], CdrError> {
        let pad = (size - (self.at - 4) % size) % size;
        let start = self.at + pad;
        let chunk = self
            .bytes
            .get(start..start + size)
            .ok_or(CdrError::Short(what))?;
        self.at = start + size;
        Ok(chunk)
    }

    fn array<const N: usize>(&mut self, what: &'static str) -> Result<[u8; N], CdrError> {
        let chunk = self.take(N, what)?;
        Ok(chunk.try_into().unwrap_or([0; N]))
    }

    pub(crate) fn u8(&mut self, what: &'static str) -> Result<u8, CdrError> {
        Ok(self.take(1, what)?[0])
    }

    pub(crate) fn i8(&mut self, what: &'static str) -> Result<i8, CdrError> {
        Ok(i8::from_le_bytes(self.array(what)?))
    }

    pub(crate) fn bool(&mut self, what: &'static str) -> Result<bool, CdrError> {
        Ok(self.u8(what)? != 0)
    }

    pub(crate) fn i32(&mut self, what: &'static str) -> Result<i32, CdrError> {
        Ok(i32::from_le_bytes(self.array(what)?))
    }

    pub(crate) fn u32(&mut self, what: &'static str) -> Result<u32, CdrError> {
        Ok(u32::from_le_bytes(self.array(what)?))
    }

    pub(crate) fn f32(&mut self, what: &'static str) -> Result<f32, CdrError> {
        Ok(f32::from_le_bytes(self.array(what)?))
    }

    pub(crate) fn f64(&mut self, what: &'static str) -> Result<f64, CdrError> {
        Ok(f64::from_le_bytes(self.array(what)?))
    }

    /// A count of elements `size` bytes each (at least), no more than the
    /// bytes left could hold.
    pub(crate) fn count(&mut self, size: usize, what: &'static str) -> Result<usize, CdrError> {
        let n = self.u32(what)? as usize;
        if n.saturating_mul(size.max(1)) > self.bytes.len() - self.at {
            return Err(CdrError::Short(what));
        }
        Ok(n)
    }

    pub(crate) fn string(&mut self, what: &'static str) -> Result<String, CdrError> {
        let n = self.count(1, what)?;
        let raw = self.take_bytes(n, what)?;
        match raw.split_last() {
            Some((0, text)) => std::str::from_utf8(text)
                .map(str::to_owned)
                .map_err(|_| CdrError::BadString),
            // Some writers leave out an empty string's NUL.
            None => Ok(String::new()),
            Some(_) => Err(CdrError::BadString),
        }
    }

    fn take_bytes(&mut self, n: usize, what: &'static str) -> Result<&'a [u8], CdrError> {
        let chunk = self
            .bytes
            .get(self.at..self.at + n)
            .ok_or(CdrError::Short(what))?;
        self.at += n;
        Ok(chunk)
    }

    pub(crate) fn bytes(&mut self, what: &'static str) -> Result<Vec<u8>, CdrError> {
        let n = self.count(1, what)?;
        Ok(self.take_bytes(n, what)?.to_vec())
    }

    pub(crate) fn f64s<const N: usize>(
        &mut self,
        what: &'static str,
    ) -> Result<[f64; N], CdrError> {
        let mut out = [0.0; N];
        for v in &mut out {
            *v = self.f64(what)?;
        }
        Ok(out)
    }

    pub(crate) fn f32_sequence(&mut self, what: &'static str) -> Result<Vec<f32>, CdrError> {
        let n = self.count(4, what)?;
        (0..n).map(|_| self.f32(what)).collect()
    }

    pub(crate) fn f64_sequence(&mut self, what: &'static str) -> Result<Vec<f64>, CdrError> {
        let n = self.count(8, what)?;
        (0..n).map(|_| self.f64(what)).collect()
    }
}
