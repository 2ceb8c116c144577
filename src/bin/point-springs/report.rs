//! Reports: each command's result is one value that prints itself as text (its
//! [`Display`]) or as JSON (its [`Serialize`]).

use std::fmt::Display;

use serde::Serialize;

use crate::failure::Failure;

/// A command's result, printable as text or JSON.
pub trait Report: Serialize + Display {}

/// Prints `report` to standard output: pretty JSON when `json`, its text otherwise.
pub fn emit(report: &impl Report, json: bool) -> Result<(), Failure> {
    if json {
        print_json(report)
    } else {
        print!("{report}");
        Ok(())
    }
}

/// Prints `value` as pretty JSON and a newline.
pub fn print_json(value: &impl Serialize) -> Result<(), Failure> {
    let text = serde_json::to_string_pretty(value).map_err(Failure::other)?;
    println!("{text}");
    Ok(())
}
