//! Closed sets of named values a user picks by name (presets, distances, motion models, ...):
//! one trait, so that every front end lists, explains and parses them alike.

/// A value picked by name: every value, its name and one line of help.
pub trait Choice: Copy + Send + Sync + 'static {
    /// Every value, in the order they are listed.
    const VALUES: &'static [Self];

    /// The name a user types.
    fn name(self) -> &'static str;

    /// One line for help texts (empty: none).
    fn description(self) -> &'static str;

    /// Other names still accepted.
    fn aliases(self) -> Vec<&'static str> {
        Vec::new()
    }
}

#[cfg(test)]
mod tests {
    use super::Choice;
    use crate::tracker::{ctrv::Motion, levers::Coast, DistanceKind, MatcherKind, Preset};

    /// Every value's name is the one configs spell it with, and names are unique.
    fn names_as_in_configs<T: Choice + serde::Serialize>() {
        let names: Vec<&str> = T::VALUES.iter().map(|v| v.name()).collect();
        for (v, name) in T::VALUES.iter().zip(&names) {
            assert_eq!(serde_json::to_string(v).unwrap(), format!("\"{name}\""));
            assert_eq!(names.iter().filter(|n| *n == name).count(), 1, "{name}");
        }
    }

    #[test]
    fn names_match_the_config_spelling() {
        names_as_in_configs::<DistanceKind>();
        names_as_in_configs::<MatcherKind>();
        names_as_in_configs::<Motion>();
        names_as_in_configs::<Coast>();
    }

    #[test]
    fn preset_names_and_aliases_resolve() {
        for p in Preset::VALUES {
            assert_eq!(Preset::from_name(Choice::name(*p)), Some(*p));
            for a in Choice::aliases(*p) {
                assert_eq!(Preset::from_name(a), Some(*p));
            }
        }
        assert_eq!(Choice::aliases(Preset::Ab3dmot2019), vec!["ab3dmot"]);
    }
}
