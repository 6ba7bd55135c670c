//! Little-endian byte writer and a bounds-checked reader whose errors name the file and the
//! byte offset.

use std::path::Path;

use glam::DVec3;

use crate::blobby::ModelError;

/// Longest mesh name stored (longer names are cut at a character boundary).
const MAX_NAME_BYTES: usize = u16::MAX as usize;

/// Appends little-endian values.
#[derive(Default)]
pub(super) struct Writer {
    out: Vec<u8>,
}

impl Writer {
    pub fn bytes(&mut self, b: &[u8]) {
        self.out.extend_from_slice(b);
    }
    pub fn u8(&mut self, v: u8) {
        self.out.push(v);
    }
    pub fn u16(&mut self, v: u16) {
        self.bytes(&v.to_le_bytes());
    }
    pub fn u32(&mut self, v: u32) {
        self.bytes(&v.to_le_bytes());
    }
    pub fn u64(&mut self, v: u64) {
        self.bytes(&v.to_le_bytes());
    }
    /// An f64 rounded to the nearest f32.
    pub fn f32(&mut self, v: f64) {
        self.bytes(&(v as f32).to_le_bytes());
    }
    pub fn vec3(&mut self, v: DVec3) {
        self.f32(v.x);
        self.f32(v.y);
        self.f32(v.z);
    }
    /// u16 byte length, then UTF-8.
    pub fn name(&mut self, s: &str) {
        let mut end = s.len().min(MAX_NAME_BYTES);
        while !s.is_char_boundary(end) {
            end -= 1;
        }
        self.u16(end as u16);
        self.bytes(&s.as_bytes()[..end]);
    }
    pub fn finish(self) -> Vec<u8> {
        self.out
    }
}

/// Reads little-endian values; running out of data is a located [`ModelError`].
pub(super) struct Reader<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    pub fn new(path: &'a Path, bytes: &'a [u8]) -> Reader<'a> {
        Reader {
            path,
            bytes,
            pos: 0,
        }
    }

    /// Current byte offset.
    pub fn pos(&self) -> usize {
        self.pos
    }

    /// An [`ModelError::Invalid`] at byte offset `at`.
    pub fn invalid(&self, at: usize, message: &str) -> ModelError {
        ModelError::Invalid {
            path: self.path.to_path_buf(),
            message: format!("byte offset {at}: {message}"),
        }
    }

    pub fn skip(&mut self, n: usize) {
        self.pos = (self.pos + n).min(self.bytes.len());
    }

    fn take<const N: usize>(&mut self, what: &str) -> Result<[u8; N], ModelError> {
        let end = self.pos.checked_add(N).filter(|&e| e <= self.bytes.len());
        let Some(end) = end else {
            return Err(self.invalid(
                self.pos,
                &format!(
                    "file truncated: {what} needs {N} bytes but the file ends at {} bytes",
                    self.bytes.len()
                ),
            ));
        };
        let mut out = [0u8; N];
        out.copy_from_slice(&self.bytes[self.pos..end]);
        self.pos = end;
        Ok(out)
    }

    pub fn u8(&mut self, what: &str) -> Result<u8, ModelError> {
        Ok(self.take::<1>(what)?[0])
    }
    pub fn u16(&mut self, what: &str) -> Result<u16, ModelError> {
        Ok(u16::from_le_bytes(self.take(what)?))
    }
    pub fn u32(&mut self, what: &str) -> Result<u32, ModelError> {
        Ok(u32::from_le_bytes(self.take(what)?))
    }
    pub fn u64(&mut self, what: &str) -> Result<u64, ModelError> {
        Ok(u64::from_le_bytes(self.take(what)?))
    }
    /// An f32 widened to f64.
    pub fn f32(&mut self, what: &str) -> Result<f64, ModelError> {
        Ok(f32::from_le_bytes(self.take(what)?) as f64)
    }
    pub fn vec3(&mut self, what: &str) -> Result<DVec3, ModelError> {
        Ok(DVec3::new(
            self.f32(what)?,
            self.f32(what)?,
            self.f32(what)?,
        ))
    }

    /// A u16-length-prefixed UTF-8 string.
    pub fn name(&mut self, what: &str) -> Result<String, ModelError> {
        let len = self.u16(what)? as usize;
        let at = self.pos;
        if self.bytes.len() - self.pos < len {
            return Err(self.invalid(
                at,
                &format!(
                    "file truncated: {what} claims {len} bytes but only {} remain",
                    self.bytes.len() - self.pos
                ),
            ));
        }
        let s = std::str::from_utf8(&self.bytes[at..at + len])
            .map_err(|e| self.invalid(at, &format!("{what} is not UTF-8 ({e})")))?;
        self.pos += len;
        Ok(s.to_string())
    }

    /// Check that exactly `count` blobs of `size` bytes remain: a truncated file names the first
    /// incomplete blob, extra bytes are refused.
    pub fn expect_blobs(&self, count: usize, size: usize) -> Result<(), ModelError> {
        let remaining = self.bytes.len() - self.pos;
        let needed = count.saturating_mul(size);
        if remaining < needed {
            let complete = remaining / size;
            return Err(self.invalid(
                self.pos + complete * size,
                &format!(
                    "file truncated in blob {} of {count}: {count} blobs need {needed} bytes after the header, {remaining} remain",
                    complete + 1
                ),
            ));
        }
        if remaining > needed {
            return Err(self.invalid(
                self.pos + needed,
                &format!(
                    "{} unexpected bytes after the last of {count} blobs",
                    remaining - needed
                ),
            ));
        }
        Ok(())
    }
}
