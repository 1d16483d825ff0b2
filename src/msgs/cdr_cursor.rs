//! A bounds-checked reader of plain CDR (XCDR1, as ROS 2 writes it) for the few fixed ROS 2
//! messages probmot decodes by hand.
//!
//! Why not only the `cdr` crate: it decodes ROS 2's layout correctly (alignment from the end of
//! the 4-byte encapsulation header, strings whose length counts their NUL terminator), but it
//! allocates a string's claimed length before checking it against the input, so one corrupt
//! length in a log makes it allocate and zero up to 4 GiB. This reader checks every length
//! against the bytes left first.

/// A malformed CDR message.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CdrError {
    /// Fewer than 4 bytes, or an encapsulation kind other than plain CDR (big or little endian).
    #[error("bad CDR encapsulation header")]
    BadHeader,
    /// The message ends inside a field.
    #[error("message ends at byte {0}, inside a field")]
    Truncated(usize),
    /// A string that is not UTF-8.
    #[error("string at byte {0} is not UTF-8")]
    BadUtf8(usize),
    /// A sequence longer than the bytes left could hold.
    #[error("sequence of {0} elements at byte {1} is longer than the message")]
    SequenceTooLong(u32, usize),
}

/// Reads CDR fields in order; positions are relative to the end of the encapsulation header.
pub struct CdrCursor<'a> {
    data: &'a [u8],
    pos: usize,
    little_endian: bool,
}

impl<'a> CdrCursor<'a> {
    /// Starts after the encapsulation header (`00 00` big endian or `00 01` little endian; the
    /// parameter-list kinds `00 02` / `00 03` have the same layout for these messages).
    pub fn new(bytes: &'a [u8]) -> Result<Self, CdrError> {
        if bytes.len() < 4 || bytes[0] != 0 || bytes[1] > 3 {
            return Err(CdrError::BadHeader);
        }
        Ok(CdrCursor {
            data: &bytes[4..],
            pos: 0,
            little_endian: bytes[1] & 1 == 1,
        })
    }

    /// Bytes not read yet.
    pub fn remaining(&self) -> usize {
        self.data.len().saturating_sub(self.pos)
    }

    fn take<const N: usize>(&mut self) -> Result<[u8; N], CdrError> {
        // Primitives are aligned to their size.
        let pos = self.pos.next_multiple_of(N);
        let end = pos.checked_add(N).ok_or(CdrError::Truncated(self.pos))?;
        let b = self
            .data
            .get(pos..end)
            .ok_or(CdrError::Truncated(self.data.len()))?;
        self.pos = end;
        Ok(b.try_into().expect("N bytes"))
    }

    /// `uint32`.
    pub fn u32(&mut self) -> Result<u32, CdrError> {
        let b = self.take::<4>()?;
        Ok(if self.little_endian {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        })
    }

    /// `uint8` (also `byte` and `char`).
    pub fn u8(&mut self) -> Result<u8, CdrError> {
        Ok(self.take::<1>()?[0])
    }

    /// `bool`: one byte, anything but 0 is true.
    pub fn bool(&mut self) -> Result<bool, CdrError> {
        Ok(self.u8()? != 0)
    }

    /// `uint8[N]`: a fixed-size byte array (no length on the wire, no alignment).
    pub fn u8_array<const N: usize>(&mut self) -> Result<[u8; N], CdrError> {
        let end = self
            .pos
            .checked_add(N)
            .ok_or(CdrError::Truncated(self.pos))?;
        let b = self
            .data
            .get(self.pos..end)
            .ok_or(CdrError::Truncated(self.data.len()))?;
        self.pos = end;
        Ok(b.try_into().expect("N bytes"))
    }

    /// `float32`.
    pub fn f32(&mut self) -> Result<f32, CdrError> {
        let b = self.take::<4>()?;
        Ok(if self.little_endian {
            f32::from_le_bytes(b)
        } else {
            f32::from_be_bytes(b)
        })
    }

    /// `int32`.
    pub fn i32(&mut self) -> Result<i32, CdrError> {
        Ok(self.u32()? as i32)
    }

    /// `float64`.
    pub fn f64(&mut self) -> Result<f64, CdrError> {
        let b = self.take::<8>()?;
        Ok(if self.little_endian {
            f64::from_le_bytes(b)
        } else {
            f64::from_be_bytes(b)
        })
    }

    /// `string`: a `uint32` length that counts the NUL terminator, the bytes, the NUL.
    pub fn string(&mut self) -> Result<String, CdrError> {
        let len = self.u32()? as usize;
        let start = self.pos;
        if len > self.remaining() {
            return Err(CdrError::Truncated(self.data.len()));
        }
        let mut bytes = &self.data[start..start + len];
        self.pos += len;
        if let [rest @ .., 0] = bytes {
            bytes = rest;
        }
        String::from_utf8(bytes.to_vec()).map_err(|_| CdrError::BadUtf8(start))
    }

    /// The length of a sequence whose elements take at least `min_size` bytes each, checked
    /// against the bytes left.
    pub fn sequence_len(&mut self, min_size: usize) -> Result<usize, CdrError> {
        let at = self.pos;
        let n = self.u32()?;
        if (n as usize).saturating_mul(min_size.max(1)) > self.remaining() {
            return Err(CdrError::SequenceTooLong(n, at));
        }
        Ok(n as usize)
    }
}
