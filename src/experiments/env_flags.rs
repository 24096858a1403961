//! Boolean environment variables (`GRANVAL_REQUIRE_LIVE`, and the tests' own): one
//! reading for all of them. `1`/`true`/`yes`/`on` and `0`/`false`/`no`/`off` are
//! accepted (any case, surrounding blanks ignored), unset or empty is off, anything else
//! is an error naming the variable and its value: a CI script that writes
//! `GRANVAL_REQUIRE_LIVE=true` must get live engines or an error, never the recorded
//! fallback because only `1` was understood.

use anyhow::{Result, bail};

/// Live reference engines required: no recorded fallback (`--reference-mode live`).
pub(crate) const REQUIRE_LIVE: &str = "GRANVAL_REQUIRE_LIVE";

/// `value` of the variable `name` as a switch.
pub fn parse(name: &str, value: &str) -> Result<bool> {
    match value.trim().to_ascii_lowercase().as_str() {
        "" | "0" | "false" | "no" | "off" => Ok(false),
        "1" | "true" | "yes" | "on" => Ok(true),
        _ => bail!(
            "environment variable {name}={value:?}: not a switch; use 1, true, yes or on (or 0, false, no, off, or leave it unset)"
        ),
    }
}

/// The switch `name` from the environment; unset is off.
pub fn flag(name: &str) -> Result<bool> {
    match std::env::var_os(name) {
        None => Ok(false),
        Some(v) => match v.to_str() {
            Some(s) => parse(name, s),
            None => bail!("environment variable {name}={v:?}: not a switch (not UTF-8)"),
        },
    }
}

/// `GRANVAL_REQUIRE_LIVE`.
pub fn require_live() -> Result<bool> {
    flag(REQUIRE_LIVE)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn usual_spellings_are_understood_and_others_refused() {
        for v in ["1", "true", "TRUE", " 1", "yes", "On ", "\ttrue\n"] {
            assert!(parse("X", v).unwrap(), "{v:?}");
        }
        for v in ["", "  ", "0", "false", "No", "OFF"] {
            assert!(!parse("X", v).unwrap(), "{v:?}");
        }
        for v in ["2", "tru", "y", "enabled", "1 1"] {
            let e = parse("GRANVAL_REQUIRE_LIVE", v).unwrap_err().to_string();
            assert!(
                e.contains("GRANVAL_REQUIRE_LIVE") && e.contains(&format!("{v:?}")),
                "{e}"
            );
        }
    }
}
