//! Per-class values on the command line: one number for every class (`40`), or
//! `class=number,...` with `*=number` for the classes not named (`car=40,motorcycle=40`).
//! `eval --max-range` and `track --two-point-speed` read them.

use std::collections::BTreeMap;

/// A value per class name, and one for the classes not named.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PerClass {
    /// Value of each named class.
    pub named: BTreeMap<String, f64>,
    /// Value of the classes not named (`None`: they keep theirs).
    pub other: Option<f64>,
}

impl PerClass {
    /// Parses `spec`; every number must be finite and positive. `unit` names the numbers in
    /// errors (`metres`, `m/s`).
    pub fn parse(spec: &str, unit: &str) -> Result<PerClass, String> {
        let number = |s: &str| -> Result<f64, String> {
            match s.trim().parse::<f64>() {
                Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
                _ => Err(format!("'{}' is not a positive number of {unit}", s.trim())),
            }
        };
        let spec = spec.trim();
        if !spec.contains('=') {
            return Ok(PerClass {
                named: BTreeMap::new(),
                other: Some(number(spec)?),
            });
        }
        let mut out = PerClass::default();
        for part in spec.split(',').filter(|p| !p.trim().is_empty()) {
            let Some((class, value)) = part.split_once('=') else {
                return Err(format!("'{part}': expected class={unit}"));
            };
            let (class, value) = (class.trim(), number(value)?);
            if class == "*" {
                if out.other.replace(value).is_some() {
                    return Err("* (every other class) given twice".into());
                }
            } else if class.is_empty() {
                return Err(format!("'{part}': empty class name"));
            } else if out.named.insert(class.to_string(), value).is_some() {
                return Err(format!("class {class} given twice"));
            }
        }
        Ok(out)
    }

    /// The value of `class`: its own, else the one for classes not named.
    pub fn of(&self, class: &str) -> Option<f64> {
        self.named.get(class).copied().or(self.other)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_number_or_named_classes_with_a_rest() {
        let all = PerClass::parse(" 40 ", "m/s").unwrap();
        assert_eq!((all.of("car"), all.named.len()), (Some(40.0), 0));
        let some = PerClass::parse("car=40, motorcycle=35,*=10", "m/s").unwrap();
        assert_eq!(some.of("car"), Some(40.0));
        assert_eq!(some.of("motorcycle"), Some(35.0));
        assert_eq!(some.of("pedestrian"), Some(10.0));
        let only = PerClass::parse("car=40", "m/s").unwrap();
        assert_eq!(only.of("pedestrian"), None);
        for (bad, says) in [
            ("0", "not a positive number of m/s"),
            ("car=-1", "'-1' is not"),
            ("car=inf", "'inf' is not"),
            ("car", "not a positive number"),
            ("car=1,bus", "'bus': expected class=m/s"),
            ("=3", "empty class name"),
            ("car=1,car=2", "class car given twice"),
            ("*=1,car=3,*=2", "* (every other class) given twice"),
        ] {
            let err = PerClass::parse(bad, "m/s").unwrap_err();
            assert!(err.contains(says), "{bad}: {err}");
        }
    }
}
