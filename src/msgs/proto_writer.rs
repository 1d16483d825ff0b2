//! A protobuf (proto3) writer for the messages probmot writes once per frame, field by field into
//! a reused buffer: no message structs, no strings built on the heap. It writes what prost writes
//! for the same values (fields in the order they are called, proto3 defaults left out), so a
//! message written by hand decodes, and compares byte for byte, like its prost counterpart.

use std::fmt;
use std::io::Write as _;

const VARINT: u32 = 0;
const FIXED64: u32 = 1;
const LEN: u32 = 2;

/// Appends protobuf fields to a buffer.
pub struct ProtoWriter<'a> {
    buf: &'a mut Vec<u8>,
}

fn varint_len(v: u64) -> usize {
    (64 - (v | 1).leading_zeros() as usize).div_ceil(7)
}

impl<'a> ProtoWriter<'a> {
    /// A writer appending to `buf` (not cleared).
    pub fn new(buf: &'a mut Vec<u8>) -> Self {
        ProtoWriter { buf }
    }

    fn varint(&mut self, mut v: u64) {
        while v >= 0x80 {
            self.buf.push((v as u8) | 0x80);
            v >>= 7;
        }
        self.buf.push(v as u8);
    }

    fn key(&mut self, field: u32, wire: u32) {
        self.varint(u64::from(field << 3 | wire));
    }

    /// A `double`, left out when it is 0 (as proto3 writes it; -0 too, as prost does).
    pub fn double(&mut self, field: u32, v: f64) {
        if v != 0.0 {
            self.key(field, FIXED64);
            self.buf.extend_from_slice(&v.to_le_bytes());
        }
    }

    /// A `uint32`/`uint64`/enum, left out when it is 0.
    pub fn uint(&mut self, field: u32, v: u64) {
        if v != 0 {
            self.key(field, VARINT);
            self.varint(v);
        }
    }

    /// A `bool`, left out when false.
    pub fn bool(&mut self, field: u32, v: bool) {
        self.uint(field, u64::from(v));
    }

    /// A `string`, left out when empty.
    pub fn string(&mut self, field: u32, s: &str) {
        if !s.is_empty() {
            self.key(field, LEN);
            self.varint(s.len() as u64);
            self.buf.extend_from_slice(s.as_bytes());
        }
    }

    /// A `string` made of `parts` one after the other, left out when empty.
    pub fn string_parts(&mut self, field: u32, parts: &[&[u8]]) {
        let len: usize = parts.iter().map(|p| p.len()).sum();
        if len > 0 {
            self.key(field, LEN);
            self.varint(len as u64);
            for p in parts {
                self.buf.extend_from_slice(p);
            }
        }
    }

    /// A `string` formatted in place (no heap string), left out when empty.
    pub fn string_fmt(&mut self, field: u32, args: fmt::Arguments<'_>) {
        let start = self.buf.len();
        self.message(field, |w| {
            w.buf.write_fmt(args).expect("a Vec grows as needed");
        });
        if self.buf.len() == start + 2 {
            self.buf.truncate(start); // empty: key and zero length only
        }
    }

    /// An embedded message (always written, as a present optional or a repeated entry): its
    /// fields are written by `fill`, then its length is put in front of them.
    pub fn message(&mut self, field: u32, fill: impl FnOnce(&mut ProtoWriter<'_>)) {
        self.key(field, LEN);
        let at = self.buf.len();
        self.buf.push(0); // one byte for the length; moved up if it needs more
        fill(self);
        let len = self.buf.len() - at - 1;
        let n = varint_len(len as u64);
        if n > 1 {
            let end = self.buf.len();
            self.buf.resize(end + n - 1, 0);
            self.buf.copy_within(at + 1..end, at + n);
        }
        let mut v = len as u64;
        for b in &mut self.buf[at..at + n] {
            *b = (v as u8 & 0x7f) | if v >= 0x80 { 0x80 } else { 0 };
            v >>= 7;
        }
    }
}

/// The decimal digits of `v`, as `{v}` formats them, in `digits` (no heap, no `fmt`).
pub fn decimal(v: u64, digits: &mut [u8; 20]) -> &[u8] {
    let mut i = digits.len();
    let mut v = v;
    loop {
        i -= 1;
        digits[i] = b'0' + (v % 10) as u8;
        v /= 10;
        if v == 0 {
            return &digits[i..];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use prost::Message as _;

    /// A message with every kind of field the writer writes, to compare with prost.
    #[derive(Clone, PartialEq, prost::Message)]
    struct Probe {
        #[prost(double, tag = "1")]
        d: f64,
        #[prost(uint64, tag = "2")]
        u: u64,
        #[prost(bool, tag = "3")]
        b: bool,
        #[prost(string, tag = "4")]
        s: String,
        #[prost(message, repeated, tag = "200")]
        inner: Vec<Probe>,
    }

    fn write(p: &Probe, w: &mut ProtoWriter<'_>) {
        w.double(1, p.d);
        w.uint(2, p.u);
        w.bool(3, p.b);
        w.string_fmt(4, format_args!("{}", p.s));
        for i in &p.inner {
            w.message(200, |w| write(i, w));
        }
    }

    fn probe() -> impl proptest::strategy::Strategy<Value = Probe> {
        use proptest::prelude::*;
        let d = prop_oneof![Just(0.0), Just(-0.0), Just(f64::NAN), any::<f64>()];
        let leaf =
            (d, any::<u64>(), any::<bool>(), ".{0,3}|.{100,200}").prop_map(|(d, u, b, s)| Probe {
                d,
                u,
                b,
                s,
                inner: Vec::new(),
            });
        leaf.prop_recursive(3, 40, 4, |inner| {
            (inner.clone(), proptest::collection::vec(inner, 0..4)).prop_map(|(mut p, v)| {
                p.inner = v;
                p
            })
        })
    }

    proptest::proptest! {
        /// The bytes are prost's, whatever the values and the lengths of nested messages.
        #[test]
        fn writes_what_prost_writes(p in probe()) {
            let mut buf = vec![7];
            write(&p, &mut ProtoWriter::new(&mut buf));
            let mut want = vec![7];
            p.encode(&mut want).unwrap();
            proptest::prop_assert_eq!(buf, want);
        }
    }

    #[test]
    fn decimal_is_display() {
        for v in [0, 7, 10, 99, 12_345, u64::MAX] {
            assert_eq!(decimal(v, &mut [0; 20]), v.to_string().as_bytes());
        }
        let mut buf = Vec::new();
        ProtoWriter::new(&mut buf).string_parts(1, &[b"ab", b"", b"c"]);
        assert_eq!(buf, [10, 3, b'a', b'b', b'c']);
        buf.clear();
        ProtoWriter::new(&mut buf).string_parts(1, &[b""]);
        assert!(buf.is_empty());
    }

    #[test]
    fn varint_lengths() {
        for (v, n) in [
            (0, 1),
            (127, 1),
            (128, 2),
            (16_383, 2),
            (16_384, 3),
            (u64::MAX, 10),
        ] {
            assert_eq!(varint_len(v), n, "{v}");
        }
    }
}
