//! Protobuf bytes in which some strings are not UTF-8, made decodable. prost refuses a whole
//! message for one such string; a reader that only needs to drop the box the string belongs to
//! re-encodes the message with each of them replaced by its lossy reading (U+FFFD for each bad
//! sequence), decodes that, and decides from the places noted here whether the message still
//! holds. Only the fields a [`Schema`] names are looked into, so the walk is as deep as the
//! schema and no deeper, whatever the bytes nest.

use prost::encoding::{
    decode_key, decode_varint, encode_key, encode_varint, skip_field, DecodeContext, WireType,
};

/// The fields of one message type that are strings, or messages with strings in them; every
/// other field is copied as it is.
pub struct Schema(pub &'static [(u32, Field)]);

/// What a field of a [`Schema`] holds.
pub enum Field {
    /// A protobuf `string`.
    Str,
    /// A message (or a repeated one) of this schema.
    Msg(&'static Schema),
}

/// One step of a place: a field's tag and its occurrence among the fields with that tag (the
/// index in a repeated field).
pub type Step = (u32, usize);

/// `buf` re-encoded with each string of `schema` that is not UTF-8 replaced by its lossy
/// reading, and the place of each replaced string (outermost step first), in the order of the
/// bytes; `None` when `buf` is not well-formed protobuf along the schema's fields (the caller
/// keeps its original error). Fields outside the schema are copied unread, so a decode of the
/// result still checks them.
pub fn repair(buf: &[u8], schema: &Schema) -> Option<(Vec<u8>, Vec<Vec<Step>>)> {
    let mut out = Vec::with_capacity(buf.len());
    let mut places = Vec::new();
    walk(buf, schema, &mut Vec::new(), &mut places, &mut out)?;
    Some((out, places))
}

fn walk(
    buf: &[u8],
    schema: &Schema,
    path: &mut Vec<Step>,
    places: &mut Vec<Vec<Step>>,
    out: &mut Vec<u8>,
) -> Option<()> {
    let mut seen: Vec<Step> = Vec::new();
    let mut rest = buf;
    while !rest.is_empty() {
        let start = buf.len() - rest.len();
        let (tag, wire) = decode_key(&mut rest).ok()?;
        let field = schema.0.iter().find(|f| f.0 == tag).map(|f| &f.1);
        let (Some(field), WireType::LengthDelimited) = (field, wire) else {
            skip_field(wire, tag, &mut rest, DecodeContext::default()).ok()?;
            out.extend_from_slice(&buf[start..buf.len() - rest.len()]);
            continue;
        };
        let len = usize::try_from(decode_varint(&mut rest).ok()?).ok()?;
        let payload = rest.get(..len)?;
        rest = &rest[len..];
        path.push((tag, occurrence(&mut seen, tag)));
        encode_key(tag, wire, out);
        match field {
            Field::Str => match std::str::from_utf8(payload) {
                Ok(_) => put(payload, out),
                Err(_) => {
                    put(String::from_utf8_lossy(payload).as_bytes(), out);
                    places.push(path.clone());
                }
            },
            Field::Msg(inner) => {
                let mut nested = Vec::with_capacity(payload.len());
                walk(payload, inner, path, places, &mut nested)?;
                put(&nested, out);
            }
        }
        path.pop();
    }
    Some(())
}

/// The index of this field among those with its tag so far.
fn occurrence(seen: &mut Vec<Step>, tag: u32) -> usize {
    match seen.iter_mut().find(|s| s.0 == tag) {
        Some(s) => {
            s.1 += 1;
            s.1
        }
        None => {
            seen.push((tag, 0));
            0
        }
    }
}

/// A length-delimited payload: its length, then its bytes.
fn put(payload: &[u8], out: &mut Vec<u8>) {
    encode_varint(payload.len() as u64, out);
    out.extend_from_slice(payload);
}

#[cfg(test)]
mod tests {
    use super::*;
    use prost::Message;

    #[derive(Clone, PartialEq, Message)]
    struct Pair {
        #[prost(string, tag = "1")]
        key: String,
        #[prost(string, tag = "2")]
        value: String,
    }

    #[derive(Clone, PartialEq, Message)]
    struct Outer {
        #[prost(string, tag = "1")]
        name: String,
        #[prost(message, repeated, tag = "2")]
        pairs: Vec<Pair>,
        #[prost(double, tag = "3")]
        x: f64,
        #[prost(string, tag = "4")]
        unlisted: String,
    }

    static PAIR: Schema = Schema(&[(1, Field::Str), (2, Field::Str)]);
    static OUTER: Schema = Schema(&[(1, Field::Str), (2, Field::Msg(&PAIR))]);

    fn pair(k: &str, v: &str) -> Pair {
        Pair {
            key: k.into(),
            value: v.into(),
        }
    }

    /// `m` encoded, with each `QQQQ` replaced by bytes that are not UTF-8.
    fn garbled(m: &Outer) -> Vec<u8> {
        let mut bytes = m.encode_to_vec();
        while let Some(at) = bytes.windows(4).position(|w| w == b"QQQQ") {
            bytes[at..at + 4].copy_from_slice(&[0xc3, 0x28, 0xff, b'r']);
        }
        bytes
    }

    fn outer() -> Outer {
        Outer {
            name: "n".into(),
            pairs: vec![pair("a", "1"), pair("b", "QQQQ"), pair("QQQQ", "3")],
            x: 2.5,
            unlisted: "u".into(),
        }
    }

    #[test]
    fn bad_strings_are_replaced_and_placed() {
        let bytes = garbled(&outer());
        assert!(Outer::decode(bytes.as_slice()).is_err());
        let (fixed, places) = repair(&bytes, &OUTER).unwrap();
        let m = Outer::decode(fixed.as_slice()).unwrap();
        let lossy = "\u{fffd}(\u{fffd}r";
        assert_eq!(m.pairs[1].value, lossy);
        assert_eq!(m.pairs[2].key, lossy);
        assert_eq!((m.name.as_str(), m.x, m.unlisted.as_str()), ("n", 2.5, "u"));
        assert_eq!(places, vec![vec![(2, 1), (2, 0)], vec![(2, 2), (1, 0)]]);
    }

    #[test]
    fn valid_bytes_come_back_unchanged() {
        let bytes = Outer {
            name: "QQ".into(),
            ..outer()
        };
        let bytes = bytes.encode_to_vec();
        assert_eq!(repair(&bytes, &OUTER).unwrap(), (bytes, Vec::new()));
    }

    #[test]
    fn a_string_outside_the_schema_is_left_for_the_decode_to_refuse() {
        let bytes = garbled(&Outer {
            pairs: vec![],
            unlisted: "QQQQ".into(),
            ..outer()
        });
        let (fixed, places) = repair(&bytes, &OUTER).unwrap();
        assert!(places.is_empty());
        assert!(Outer::decode(fixed.as_slice()).is_err());
    }

    #[test]
    fn malformed_bytes_are_refused() {
        let bytes = garbled(&outer());
        for cut in 1..bytes.len() {
            if let Some((fixed, _)) = repair(&bytes[..cut], &OUTER) {
                // A cut between two fields is well-formed: it decodes as fewer fields.
                Outer::decode(fixed.as_slice()).unwrap();
            }
        }
        assert!(repair(&[0x0a, 0x05, b'a'], &OUTER).is_none());
    }
}
