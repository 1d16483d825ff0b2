//! The error of a configuration that cannot be used (its own file so that the config and the
//! levers it holds can both name it without importing each other).

/// A configuration that cannot be used, with the reason.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("invalid tracker config: {0}")]
pub struct ConfigError(pub String);
