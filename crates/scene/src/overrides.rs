//! `-D key=value`: setting a scene's values from the command line.
//!
//! An override names a key of the scene file by its dotted path (`camera.eye`, `image.width`,
//! `radiosity.max_depth`, `display.exposure`) and gives a TOML value (`[0, 1, 3]`, `800`,
//! `"texture-bicubic"`; a bare word that is not a TOML value is taken as a string). The file is
//! read into a TOML table, every override is set on it in order (creating missing tables), and
//! the result is validated like any scene file, so an override is held to every rule a file is.
//! Arrays of tables (`[[materials]]`, `[[obj]]`) cannot be addressed by a dotted key and are
//! refused by name.
//!
//! The merged text is not the file's, so its line numbers mean nothing to the user: an error
//! the file has without the overrides is reported at the file's own line (by validating the
//! file alone), any other is blamed on the overrides by `blame`.

use base::error::{Error, Location, Result};
use std::path::Path;

/// The option name overrides are reported under.
const OPTION: &str = "define";

/// Parses one `key=value` argument.
pub fn parse(arg: &str) -> Result<(String, String)> {
    let Some((k, v)) = arg.split_once('=') else {
        return Err(Error::invalid_option(
            OPTION,
            arg,
            "expected key=value, for example camera.eye=[0,1,3] or image.width=800",
        ));
    };
    let k = k.trim();
    if k.is_empty() || k.split('.').any(|p| p.trim().is_empty()) {
        return Err(Error::invalid_option(
            OPTION,
            arg,
            "the key must be a dotted path of names, for example camera.eye",
        ));
    }
    Ok((k.to_string(), v.trim().to_string()))
}

/// A TOML value from the command line: TOML syntax, else the text as a string.
fn value(text: &str) -> toml::Value {
    match toml::from_str::<toml::Table>(&format!("v = {text}")) {
        Ok(mut t) => t
            .remove("v")
            .unwrap_or(toml::Value::String(text.to_string())),
        Err(_) => toml::Value::String(text.to_string()),
    }
}

/// `text` (the scene file at `path`) with every override set, as TOML text.
pub(crate) fn apply(text: &str, path: &Path, overrides: &[(String, String)]) -> Result<String> {
    let mut table: toml::Table = toml::from_str(text).map_err(|e| {
        let mut loc = Location::file(path);
        if let Some(span) = e.span() {
            loc = loc.at_line(crate::checks::line_of(text, span.start));
        }
        Error::input(loc, e.message().trim_end().to_string())
    })?;
    for (key, v) in overrides {
        set(&mut table, key, value(v))
            .map_err(|reason| Error::invalid_option(OPTION, format!("{key}={v}"), reason))?;
    }
    toml::to_string(&table).map_err(|e| Error::internal(format!("scene with overrides: {e}")))
}

/// Sets the dotted `key` of `table` to `v`, creating the tables on its way.
fn set(table: &mut toml::Table, key: &str, v: toml::Value) -> std::result::Result<(), String> {
    let parts: Vec<&str> = key.split('.').map(str::trim).collect();
    let (last, path) = parts.split_last().ok_or("empty key")?;
    let mut t = table;
    for (i, p) in path.iter().enumerate() {
        let entry = t
            .entry(p.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        t = match entry {
            toml::Value::Table(inner) => inner,
            _ => {
                return Err(format!(
                    "`{}` is not a table (a list like [[materials]] cannot be set with -D)",
                    path[..=i].join(".")
                ))
            }
        };
    }
    let tables =
        |v: &toml::Value| matches!(v, toml::Value::Array(a) if a.iter().any(toml::Value::is_table));
    if tables(&v) || t.get(*last).is_some_and(tables) {
        return Err(format!(
            "`{key}` is a list of tables (like [[{last}]]), which cannot be set with -D: edit \
             the scene file"
        ));
    }
    t.insert(last.to_string(), v);
    Ok(())
}

/// An error of a scene that is valid without its overrides: the overrides made it, so the error
/// names them (the merged text's line would point nowhere the user can look).
pub(crate) fn blame(e: Error, overrides: &[(String, String)]) -> Error {
    let given: Vec<String> = overrides.iter().map(|(k, v)| format!("{k}={v}")).collect();
    let reason = match e {
        Error::Input { location, message } => match location.key {
            Some(k) => format!("{k}: {message}"),
            None => message,
        },
        e => e.to_string(),
    };
    Error::invalid_option(
        OPTION,
        given.join(" "),
        format!("{reason} (values are TOML: a list [0, 1.5, 3], a number 800, a string \"name\")"),
    )
}
