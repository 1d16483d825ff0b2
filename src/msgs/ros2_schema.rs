//! The field lists of the message types a ROS 2 schema record defines, so that a CDR decoder can
//! check a channel's field layout before it reads any bytes (CDR carries no field names).
//!
//! rosbag2 stores a type's definition with every dependency in the MCAP schema record, in one of
//! two encodings:
//!
//! - `ros2msg`: the `.msg` text of the type, then per dependency a line of `=` characters,
//!   `MSG: package/Type` and its `.msg` text;
//! - `ros2idl`: the same with `IDL: package/msg/Type` and IDL text (for packages whose
//!   interfaces are written in IDL, e.g. `autoware_auto_perception_msgs`).
//!
//! Both are read into one form: per type name without package (`Header`, `DetectedObject`), its
//! fields as `(type, name)` in `.msg` spelling: the type without package (`Pose`,
//! `ObjectClassification[]`, `uint8[16]`, `float32`), constants left out.

use std::collections::BTreeMap;

/// `(type, name)` of each field, as the `.msg` text writes them.
pub type Fields = Vec<(String, String)>;

/// The fields of each message type of a schema record, by type name without package.
pub type Sections = BTreeMap<String, Fields>;

/// One message type a layout expects: its name, whether the schema text must define it (the
/// package's own types) or is only checked when it does (the standard types), and its fields.
pub struct Expected {
    /// Type name without package.
    pub name: &'static str,
    /// Must be defined by the schema text.
    pub required: bool,
    /// Its fields in order.
    pub fields: Fields,
}

/// The fields of each message type a `ros2msg` schema text defines; the top-level type (the
/// text before the first separator) is stored under `top`.
pub fn parse_msg(text: &str, top: &str) -> Sections {
    let mut out = Sections::new();
    let mut current = top.to_string();
    let mut after_separator = false;
    out.entry(current.clone()).or_default();
    for raw in text.lines() {
        let line = raw.split('#').next().unwrap_or("").trim();
        if line.starts_with("===") {
            after_separator = true;
            continue;
        }
        if after_separator {
            if let Some(name) = line.strip_prefix("MSG:") {
                current = base_name(name.trim()).to_string();
                out.entry(current.clone()).or_default();
                after_separator = false;
                continue;
            }
        }
        let tokens: Vec<&str> = line.split_whitespace().collect();
        if tokens.len() < 2 {
            continue;
        }
        // Constants: `TYPE NAME=VALUE` or `TYPE NAME = VALUE`.
        if tokens[1].contains('=') || tokens.get(2) == Some(&"=") {
            continue;
        }
        out.entry(current.clone())
            .or_default()
            .push((base_name(tokens[0]).to_string(), tokens[1].to_string()));
    }
    out
}

/// `pkg/msg/Type` or `pkg/Type` -> `Type` (array suffixes kept).
pub fn base_name(t: &str) -> &str {
    t.rsplit('/').next().unwrap_or(t)
}

/// The fields of every `struct` a `ros2idl` schema text defines (comments, annotations and
/// constant modules skipped), with IDL types spelled as in `.msg` files: `sequence<T>` is `T[]`,
/// a member array `T name[N]` is `T[N]`, `double` is `float64`, `boolean` is `bool`,
/// `pkg::msg::Type` is `Type`.
pub fn parse_idl(text: &str) -> Sections {
    let tokens = idl_tokens(text);
    let aliases = idl_typedefs(&tokens);
    let mut out = Sections::new();
    let mut i = 0;
    while i + 2 < tokens.len() {
        if tokens[i] == "struct" && tokens[i + 2] == "{" {
            let name = tokens[i + 1].clone();
            let mut fields = Fields::new();
            let mut member: Vec<&str> = Vec::new();
            i += 3;
            while i < tokens.len() && tokens[i] != "}" {
                if tokens[i] == ";" {
                    if let Some((ty, name)) = idl_member(&member) {
                        fields.push((resolve_alias(ty, &aliases), name));
                    }
                    member.clear();
                } else {
                    member.push(&tokens[i]);
                }
                i += 1;
            }
            out.insert(name, fields);
        }
        i += 1;
    }
    out
}

/// The array typedefs of an IDL text (`typedef double double__36[36];`, as rosidl writes a
/// fixed-size array field): alias -> `.msg` spelling (`float64[36]`).
fn idl_typedefs(tokens: &[String]) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    for (i, _) in tokens.iter().enumerate().filter(|(_, t)| *t == "typedef") {
        let Some(end) = tokens[i..].iter().position(|t| t == ";") else {
            continue;
        };
        let decl: Vec<&str> = tokens[i + 1..i + end].iter().map(String::as_str).collect();
        if let Some((ty, name)) = idl_member(&decl) {
            out.insert(name, ty);
        }
    }
    out
}

/// `ty` with a typedef alias (also as a sequence's element type) replaced by what it names.
fn resolve_alias(ty: String, aliases: &BTreeMap<String, String>) -> String {
    let (base, suffix) = match ty.find('[') {
        Some(k) => ty.split_at(k),
        None => (ty.as_str(), ""),
    };
    match aliases.get(base) {
        Some(named) => format!("{named}{suffix}"),
        None => ty,
    }
}

/// The tokens of an IDL text: identifiers and numbers, `::`, and single punctuation characters;
/// comments, string literals and annotations (`@name` with its parenthesised arguments) dropped.
fn idl_tokens(text: &str) -> Vec<String> {
    let chars: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let next = chars.get(i + 1).copied();
        if c.is_whitespace() {
            i += 1;
        } else if c == '/' && next == Some('/') {
            while i < chars.len() && chars[i] != '\n' {
                i += 1;
            }
        } else if c == '/' && next == Some('*') {
            i += 2;
            while i < chars.len() && !(chars[i] == '*' && chars.get(i + 1) == Some(&'/')) {
                i += 1;
            }
            i += 2;
        } else if c == '"' {
            i = skip_string(&chars, i);
        } else if c == '@' {
            i += 1;
            while i < chars.len() && (chars[i].is_alphanumeric() || chars[i] == '_') {
                i += 1;
            }
            while i < chars.len() && chars[i].is_whitespace() {
                i += 1;
            }
            if chars.get(i) == Some(&'(') {
                i = skip_parens(&chars, i);
            }
        } else if c == ':' && next == Some(':') {
            out.push("::".to_string());
            i += 2;
        } else if c.is_alphanumeric() || c == '_' {
            let start = i;
            while i < chars.len() && (chars[i].is_alphanumeric() || chars[i] == '_') {
                i += 1;
            }
            out.push(chars[start..i].iter().collect());
        } else {
            out.push(c.to_string());
            i += 1;
        }
    }
    out
}

/// The index after the string literal starting at `i` (a `"`), escapes included.
fn skip_string(chars: &[char], mut i: usize) -> usize {
    i += 1;
    while i < chars.len() && chars[i] != '"' {
        i += if chars[i] == '\\' { 2 } else { 1 };
    }
    i + 1
}

/// The index after the balanced parentheses starting at `i` (a `(`), string literals skipped.
fn skip_parens(chars: &[char], mut i: usize) -> usize {
    let mut depth = 0usize;
    while i < chars.len() {
        match chars[i] {
            '"' => {
                i = skip_string(chars, i);
                continue;
            }
            '(' => depth += 1,
            ')' => {
                depth -= 1;
                if depth == 0 {
                    return i + 1;
                }
            }
            _ => {}
        }
        i += 1;
    }
    i
}

/// `(type, name)` of one struct member's tokens (without the `;`).
fn idl_member(tokens: &[&str]) -> Option<(String, String)> {
    let (ty, name) = match tokens {
        [ty @ .., name, "[", n, "]"] => (format!("{}[{n}]", idl_type(ty)?), name),
        [ty @ .., name] => (idl_type(ty)?, name),
        _ => return None,
    };
    Some((ty, name.to_string()))
}

/// The `.msg` spelling of an IDL type's tokens.
fn idl_type(tokens: &[&str]) -> Option<String> {
    match tokens {
        [] => None,
        ["sequence", "<", inner @ .., ">"] => {
            // `sequence<T>` or `sequence<T, N>` (bounded; the comma is never inside T here).
            match inner.iter().position(|t| *t == ",") {
                Some(k) => Some(format!(
                    "{}[<={}]",
                    idl_type(&inner[..k])?,
                    inner[k + 1..].concat()
                )),
                None => Some(format!("{}[]", idl_type(inner)?)),
            }
        }
        [s @ ("string" | "wstring"), "<", n, ">"] => Some(format!("{s}<={n}")),
        _ => {
            let joined = tokens.join(" ").replace(" :: ", "::");
            let base = joined.rsplit("::").next().unwrap_or(&joined);
            Some(
                match base {
                    "boolean" => "bool",
                    "octet" => "byte",
                    "float" => "float32",
                    "double" => "float64",
                    "short" => "int16",
                    "unsigned short" => "uint16",
                    "long" => "int32",
                    "unsigned long" => "uint32",
                    "long long" => "int64",
                    "unsigned long long" => "uint64",
                    other => other,
                }
                .to_string(),
            )
        }
    }
}

/// The sections of a schema record by its encoding (`ros2msg` or `ros2idl`), or why it cannot
/// be read.
pub fn parse(schema_encoding: &str, schema_data: &[u8], top: &str) -> Result<Sections, String> {
    let text =
        std::str::from_utf8(schema_data).map_err(|_| "the schema text is not UTF-8".to_string())?;
    if text.trim().is_empty() {
        return Err(
            "the schema record holds no definition text, so the field layout cannot be checked"
                .into(),
        );
    }
    match schema_encoding {
        "ros2msg" => Ok(parse_msg(text, top)),
        "ros2idl" => Ok(parse_idl(text)),
        other => Err(format!(
            "schema encoding '{other}' (probmot reads ros2msg or ros2idl schema texts)"
        )),
    }
}

/// Builds a field list from `(type, name)` pairs.
pub fn fields(spec: &[(&str, &str)]) -> Fields {
    spec.iter()
        .map(|(t, n)| (t.to_string(), n.to_string()))
        .collect()
}

/// `type name, type name` (or `no fields`).
pub fn show(f: &Fields) -> String {
    if f.is_empty() {
        return "no fields".into();
    }
    f.iter()
        .map(|(t, n)| format!("{t} {n}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Why `sections` does not have the layout `expected` (called `layout` in the message), or `Ok`.
pub fn check(sections: &Sections, expected: &[Expected], layout: &str) -> Result<(), String> {
    for e in expected {
        match sections.get(e.name) {
            Some(got) if *got == e.fields => {}
            Some(got) => {
                return Err(format!(
                    "{} has fields [{}]; the {layout} has [{}]",
                    e.name,
                    show(got),
                    show(&e.fields)
                ))
            }
            None if e.required => {
                return Err(format!(
                    "the schema text does not define {}, so the field layout cannot be checked",
                    e.name
                ))
            }
            None => {}
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn msg_text_sections_without_constants_or_comments() {
        let text = "std_msgs/Header header # the stamp\nThing[] things\n\
            ================================================================================\n\
            MSG: pkg/Thing\nuint8 A=1\nuint8 B = 2\nuint8[16] uuid\nfloat32 p\n";
        let s = parse_msg(text, "Things");
        assert_eq!(
            s["Things"],
            fields(&[("Header", "header"), ("Thing[]", "things")])
        );
        assert_eq!(
            s["Thing"],
            fields(&[("uint8[16]", "uuid"), ("float32", "p")])
        );
    }

    #[test]
    fn idl_text_sections_in_msg_spelling() {
        // The shape of an IDL schema record: comments, annotations with parentheses inside
        // their strings, constant modules, scoped and sequence types, a member array.
        let text = r#"================================================================================
IDL: pkg/msg/Thing
#include "geometry_msgs/msg/Pose.idl"
module pkg {
  module msg {
    typedef double double__36[36];
    module Thing_Constants {
      const uint8 CAR = 1; // a comment
    };
    /* block
       comment */
    struct Thing {
      @verbatim (language="comment", text=
        " x: the length (BOUNDING_BOX) or diameter (CYLINDER)")
      geometry_msgs::msg::Pose pose;
      @range (min=0.0, max=1.0)
      float probability;
      sequence<pkg::msg::Other> others;
      sequence<double, 3> bounded;
      double__36 covariance;
      boolean flag;
      unsigned long count;
      uint8 uuid[16];
      @value (default=False)
      boolean is_stationary;
    };
  };
};
"#;
        let s = parse_idl(text);
        assert_eq!(
            s["Thing"],
            fields(&[
                ("Pose", "pose"),
                ("float32", "probability"),
                ("Other[]", "others"),
                ("float64[<=3]", "bounded"),
                ("float64[36]", "covariance"),
                ("bool", "flag"),
                ("uint32", "count"),
                ("uint8[16]", "uuid"),
                ("bool", "is_stationary"),
            ])
        );
        assert_eq!(s.len(), 1, "{s:?}");
    }

    #[test]
    fn check_names_the_first_difference() {
        let s = parse_msg("int32 a\n", "Top");
        let want = |f| Expected {
            name: "Top",
            required: true,
            fields: fields(f),
        };
        assert!(check(&s, &[want(&[("int32", "a")])], "x layout").is_ok());
        let e = check(&s, &[want(&[("int64", "a")])], "x layout").unwrap_err();
        assert_eq!(e, "Top has fields [int32 a]; the x layout has [int64 a]");
        let missing = Expected {
            name: "Other",
            required: true,
            fields: Fields::new(),
        };
        assert!(check(&s, &[missing], "x")
            .unwrap_err()
            .contains("does not define Other"));
    }
}
