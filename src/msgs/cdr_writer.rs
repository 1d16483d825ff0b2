//! A little-endian plain CDR (XCDR1) writer for the ROS 2 messages probmot writes (its tracks as
//! `vision_msgs` or Autoware messages): primitives aligned to their size, counted from the end of
//! the 4-byte encapsulation header, as ROS 2 (Fast DDS, Cyclone DDS) writes them.

/// Appends CDR fields to a buffer that starts with the encapsulation header.
pub struct CdrWriter<'a> {
    buf: &'a mut Vec<u8>,
}

impl<'a> CdrWriter<'a> {
    /// Clears `buf` and writes the little-endian encapsulation header `00 01 00 00`.
    pub fn new(buf: &'a mut Vec<u8>) -> Self {
        buf.clear();
        buf.extend_from_slice(&[0, 1, 0, 0]);
        CdrWriter { buf }
    }

    fn align(&mut self, n: usize) {
        let pos = self.buf.len() - 4;
        let pad = pos.next_multiple_of(n) - pos;
        self.buf.resize(self.buf.len() + pad, 0);
    }

    /// `uint8`.
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }

    /// `bool`.
    pub fn bool(&mut self, v: bool) {
        self.buf.push(u8::from(v));
    }

    /// `uint8[N]`: the bytes, no length.
    pub fn bytes(&mut self, v: &[u8]) {
        self.buf.extend_from_slice(v);
    }

    /// `uint32` (also a sequence length).
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// `int32`.
    pub fn i32(&mut self, v: i32) {
        self.u32(v as u32);
    }

    /// `float32`.
    pub fn f32(&mut self, v: f32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// `float64`.
    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `string`: length counting the NUL, the bytes, the NUL.
    pub fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }

    /// `builtin_interfaces/Time` + frame id: a `std_msgs/Header`.
    pub fn header(&mut self, stamp: u64, frame_id: &str) {
        let sec = stamp / 1_000_000_000;
        // Stamps past 2038 do not fit `int32 sec`; they saturate (ROS 2 has the same limit).
        self.i32(i32::try_from(sec).unwrap_or(i32::MAX));
        self.u32((stamp % 1_000_000_000) as u32);
        self.string(frame_id);
    }

    /// `geometry_msgs/Pose` of a box centre rotated by `yaw` about +z.
    pub fn pose(&mut self, center: [f64; 3], yaw: f64) {
        for v in center {
            self.f64(v);
        }
        let (s, c) = (yaw / 2.0).sin_cos();
        for v in [0.0, 0.0, s, c] {
            self.f64(v);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_aligned_from_the_end_of_the_header() {
        let mut buf = vec![9, 9];
        let mut w = CdrWriter::new(&mut buf);
        w.u8(7);
        w.f64(1.0);
        w.bool(true);
        w.f32(2.0);
        w.string("ab");
        let mut want = vec![0, 1, 0, 0, 7, 0, 0, 0, 0, 0, 0, 0];
        want.extend(1.0f64.to_le_bytes());
        want.extend([1, 0, 0, 0]);
        want.extend(2.0f32.to_le_bytes());
        want.extend(3u32.to_le_bytes());
        want.extend(b"ab\0");
        assert_eq!(buf, want);
    }
}
