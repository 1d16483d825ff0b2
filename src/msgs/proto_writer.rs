//! A protobuf (proto3) writer for the messages probmot writes once per frame, field by field into
//! a reused buffer: no message structs, no strings built on the heap. It writes what prost writes
//! for the same values (fields in the order they are called, proto3 defaults left out), so a
//! message written by hand decodes, and compares byte for byte, like its prost counterpart.

use std::fmt;
use std::io::Write as _;

const VARINT: u32 = 0;
const FIXED64: u32 = 1;
const LEN: u32 = 2;

/// Doubles of a message that [`ProtoWriter::doubles`] writes in one piece (one-byte keys, a
/// body under 128 bytes).
const SHORT_DOUBLES: usize = 4;

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
        let key_len = varint_len(u64::from(field << 3 | LEN));
        if self.buf.len() == start + key_len + 1 {
            self.buf.truncate(start); // empty: key and zero length only
        }
    }

    /// An embedded message whose fields 1, 2, ... are `values`: the shape of every message of
    /// doubles in the schemas (a vector, a size, a quaternion, a colour, an image box).
    ///
    /// Up to four values (every such message in the schemas) are put together on
    /// the stack and appended at once: the body is shorter than 128 bytes, so its length takes
    /// one byte and nothing has to move.
    pub fn doubles(&mut self, field: u32, values: &[f64]) {
        if values.len() > SHORT_DOUBLES {
            return self.message(field, |w| {
                for (k, &v) in (1..).zip(values) {
                    w.double(k, v);
                }
            });
        }
        let mut body = [0u8; 9 * SHORT_DOUBLES];
        let mut n = 0;
        for (k, &v) in (1u8..).zip(values) {
            if v != 0.0 {
                body[n] = k << 3 | FIXED64 as u8;
                body[n + 1..n + 9].copy_from_slice(&v.to_le_bytes());
                n += 9;
            }
        }
        self.key(field, LEN);
        self.buf.push(n as u8);
        self.buf.extend_from_slice(&body[..n]);
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

/// `v` with three decimals (`0.870`, `-12.000`), rounded to the nearest thousandth, in `buf`
/// (no heap, no `fmt`); `None` when `v` is not finite or its magnitude reaches 10^15 (where a
/// double has no thousandths).
pub fn three_decimals(v: f64, buf: &mut [u8; 24]) -> Option<&[u8]> {
    if !v.is_finite() || v.abs() >= 1e15 {
        return None;
    }
    let m = (v.abs() * 1000.0).round() as u64;
    let mut digits = [0; 20];
    let int = decimal(m / 1000, &mut digits);
    let mut n = 0;
    if v < 0.0 && m != 0 {
        buf[0] = b'-';
        n = 1;
    }
    buf[n..n + int.len()].copy_from_slice(int);
    n += int.len();
    let frac = m % 1000;
    buf[n..n + 4].copy_from_slice(&[
        b'.',
        b'0' + (frac / 100) as u8,
        b'0' + (frac / 10 % 10) as u8,
        b'0' + (frac % 10) as u8,
    ]);
    Some(&buf[..n + 4])
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
        /// A field whose key takes two bytes.
        #[prost(string, tag = "20")]
        s20: String,
        #[prost(message, repeated, tag = "200")]
        inner: Vec<Probe>,
    }

    fn write(p: &Probe, w: &mut ProtoWriter<'_>) {
        w.double(1, p.d);
        w.uint(2, p.u);
        w.bool(3, p.b);
        w.string_fmt(4, format_args!("{}", p.s));
        w.string_fmt(20, format_args!("{}", p.s20));
        for i in &p.inner {
            w.message(200, |w| write(i, w));
        }
    }

    fn probe() -> impl proptest::strategy::Strategy<Value = Probe> {
        use proptest::prelude::*;
        let d = prop_oneof![Just(0.0), Just(-0.0), Just(f64::NAN), any::<f64>()];
        let text = ".{0,3}|.{100,200}";
        // Around 16 KiB too: a message that holds one takes a three-byte length (2^14 and up).
        let long_text = prop_oneof![
            text.boxed(),
            (16370..16400usize).prop_map(|n| "x".repeat(n)).boxed()
        ];
        let leaf =
            (d, any::<u64>(), any::<bool>(), text, long_text).prop_map(|(d, u, b, s, s20)| Probe {
                d,
                u,
                b,
                s,
                s20,
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
        /// `doubles` writes what `message` with one `double` per value writes (prost's bytes,
        /// see below), on its short path and past it, under one- and two-byte keys.
        #[test]
        fn doubles_is_a_message_of_doubles(
            field in proptest::prop_oneof![1..16u32, 16..300u32],
            values in proptest::collection::vec(proptest::prop_oneof![
                proptest::strategy::Just(0.0), proptest::strategy::Just(-0.0),
                proptest::strategy::Just(f64::NAN), proptest::prelude::any::<f64>()
            ], 0..=2 * SHORT_DOUBLES),
        ) {
            let mut got = vec![7];
            ProtoWriter::new(&mut got).doubles(field, &values);
            let mut want = vec![7];
            ProtoWriter::new(&mut want).message(field, |w| {
                for (k, &v) in (1..).zip(&values) {
                    w.double(k, v);
                }
            });
            proptest::prop_assert_eq!(got, want);
        }

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

    proptest::proptest! {
        /// Three decimals, within half a thousandth of the value (what `{:.3}` writes, but for
        /// the ties that `{:.3}` rounds by the exact binary value).
        #[test]
        fn three_decimals_round_to_thousandths(v in proptest::prop_oneof![
            -2.0..2.0f64, -1e14..1e14f64, proptest::prelude::any::<f64>()
        ]) {
            let mut buf = [0; 24];
            match three_decimals(v, &mut buf) {
                None => proptest::prop_assert!(!v.is_finite() || v.abs() >= 1e15),
                Some(t) => {
                    let t = std::str::from_utf8(t).unwrap();
                    let back: f64 = t.parse().unwrap();
                    proptest::prop_assert_eq!(t.len() - t.find('.').unwrap(), 4, "{}", t);
                    proptest::prop_assert!((back - v).abs() <= 0.0005 + v.abs() * 1e-15, "{} {}", v, t);
                    // Away from ties, and where the product is exact enough: `{:.3}`'s digits
                    // (but for `-0.000`, written `0.000`).
                    let f = (v * 1000.0).fract().abs();
                    if v.abs() < 1e6 && !(0.49..=0.51).contains(&f) && t != "0.000" {
                        proptest::prop_assert_eq!(t, format!("{v:.3}"));
                    }
                }
            }
        }
    }

    #[test]
    fn three_decimals_examples() {
        let mut buf = [0; 24];
        for (v, want) in [
            (0.0, "0.000"),
            (-0.0, "0.000"),
            (0.87, "0.870"),
            (1.0, "1.000"),
            (0.12345, "0.123"),
            (0.9996, "1.000"),
            (-0.0004, "0.000"),
            (-12.5, "-12.500"),
            (123_456.789_4, "123456.789"),
        ] {
            assert_eq!(three_decimals(v, &mut buf), Some(want.as_bytes()), "{v}");
        }
        for v in [f64::NAN, f64::INFINITY, -1e15, 1e300] {
            assert_eq!(three_decimals(v, &mut buf), None, "{v}");
        }
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
