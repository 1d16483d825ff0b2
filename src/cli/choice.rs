//! Every library [`Choice`] (preset, distance, motion model, ...) as an option's values: one
//! value parser whose names, aliases and help lines come from the library.

use std::ffi::OsStr;
use std::marker::PhantomData;

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use clap::error::Error;
use probmot::tracker::Choice;

/// The value parser of an option taking one value of `T` (`value_parser = choice::<T>()`).
#[derive(Debug, Clone, Copy)]
pub struct Choices<T>(PhantomData<T>);

/// The value parser of an option taking one value of `T`.
pub fn choice<T: Choice>() -> Choices<T> {
    Choices(PhantomData)
}

/// `T`'s value as clap lists it: name, help line (when it has one) and aliases.
fn possible<T: Choice>(v: T) -> PossibleValue {
    let pv = PossibleValue::new(v.name()).aliases(v.aliases());
    match v.description() {
        "" => pv,
        d => pv.help(d),
    }
}

impl<T: Choice> TypedValueParser for Choices<T> {
    type Value = T;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &OsStr,
    ) -> Result<T, Error> {
        let values = T::VALUES.iter().map(|v| possible(*v));
        let name = PossibleValuesParser::new(values).parse_ref(cmd, arg, value)?;
        let ignore_case = arg.is_some_and(|a| a.is_ignore_case_set());
        let mut values = T::VALUES.iter().copied();
        Ok((values.find(|v| possible(*v).matches(&name, ignore_case)))
            .expect("the parser accepted a name of one of the values"))
    }

    fn possible_values(&self) -> Option<Box<dyn Iterator<Item = PossibleValue> + '_>> {
        Some(Box::new(T::VALUES.iter().map(|v| possible(*v))))
    }
}
