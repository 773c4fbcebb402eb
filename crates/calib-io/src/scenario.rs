//! Simulation scenarios (TOML), as `calib simulate` reads them: a
//! [`calib_core::simulate::Scenario`] with no unknown keys, checked by its own
//! [`validate`](calib_core::simulate::Scenario::validate). `testdata/scenarios/` holds
//! complete, commented examples.

use crate::Error;
use calib_core::simulate::Scenario;
use std::path::Path;

/// Reads and validates a scenario from `path`.
pub fn read_scenario(path: &Path) -> Result<Scenario, Error> {
    let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_scenario(&text, path)
}

/// Parses and validates a scenario; `path` names it in errors, which say what TOML's parser or
/// the scenario's checks found (with the line, where the parser names one).
pub fn parse_scenario(text: &str, path: &Path) -> Result<Scenario, Error> {
    let err = |message: String| Error::Data {
        path: path.to_path_buf(),
        message,
    };
    let scenario: Scenario =
        toml::from_str(text).map_err(|e| err(e.to_string().trim_end().to_string()))?;
    scenario.validate().map_err(|e| err(e.to_string()))?;
    Ok(scenario)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every committed scenario reads, and writing it back as TOML reads to the same scenario.
    #[test]
    fn committed_scenarios_read_back_as_written() {
        let dir = Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../testdata/scenarios"
        ));
        let mut read = 0;
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_none_or(|e| e != "toml") {
                continue;
            }
            let scenario = read_scenario(&path).unwrap();
            let text = toml::to_string(&scenario).unwrap();
            assert_eq!(
                parse_scenario(&text, &path).unwrap(),
                scenario,
                "{}",
                path.display()
            );
            read += 1;
        }
        assert!(read >= 10, "{read} scenarios");
    }

    #[test]
    fn unknown_keys_and_bad_values_name_the_file() {
        let path = Path::new("s.toml");
        let err = parse_scenario("rate_hzz = 10\n", path)
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("s.toml: ") && err.contains("rate_hzz"),
            "{err}"
        );
    }
}
