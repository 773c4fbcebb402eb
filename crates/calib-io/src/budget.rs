//! GUM uncertainty budgets in TOML (the interface document's "Uncertainty budgets").
//!
//! ```toml
//! level = 0.95                  # optional, default 0.95
//!
//! [[component]]
//! name = "Repeatability"
//! u = 0.0531                    # exactly one of: u
//! dof = 5                       #   or half_width + distribution (rectangular, triangular, u-shaped)
//!                               #   or value + divisor
//! [[component]]
//! name = "Pitch repeatability"
//! value = 0.12
//! divisor = 2.449
//! estler_faces = 24             # sensitivity 1/n − 8/(9n²) (Estler), instead of `sensitivity`
//! dof = 5
//! ```
//!
//! Per component: `sensitivity` (default 1) or `estler_faces`; `dof` (a number ≥ 1 or `"inf"`) or
//! `relative_uncertainty` (`ν = ½ rel⁻²`, GUM G.4.2); neither means `ν = ∞` (a Type B value with no
//! stated reliability). Unknown keys are errors. Every error names the component and says what to
//! write instead.

use crate::Error;
use calib_core::uncertainty::{
    Budget, Component, Distribution, dof_from_relative_uncertainty, estler_sensitivity,
};
use std::path::Path;

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBudget {
    level: Option<f64>,
    #[serde(default)]
    component: Vec<RawComponent>,
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct RawComponent {
    name: Option<String>,
    u: Option<f64>,
    half_width: Option<f64>,
    distribution: Option<String>,
    value: Option<f64>,
    divisor: Option<f64>,
    sensitivity: Option<f64>,
    estler_faces: Option<usize>,
    dof: Option<RawDof>,
    relative_uncertainty: Option<f64>,
}

#[derive(serde::Deserialize)]
#[serde(untagged)]
enum RawDof {
    Number(f64),
    Text(String),
}

/// Reads and validates a budget from `path`.
pub fn read_budget(path: &Path) -> Result<Budget, Error> {
    let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_budget(&text, path)
}

/// Parses and validates a budget; `path` names it in errors.
pub fn parse_budget(text: &str, path: &Path) -> Result<Budget, Error> {
    let raw: RawBudget = toml::from_str(text).map_err(|e| {
        let offset = e.span().map(|s| s.start);
        let line = offset.map(|o| text[..o.min(text.len())].matches('\n').count() as u64 + 1);
        // Which [[component]] table the error is in, counted from 1.
        let component = offset.and_then(|o| {
            let count = text[..o.min(text.len())].matches("[[component]]").count();
            (count > 0).then(|| format!("#{count}"))
        });
        let mut message = e.message().trim().to_string();
        if message.starts_with("unknown field") {
            message += "; see `calib uncertainty --help` for the keys of a budget";
        }
        Error::Budget {
            path: path.to_path_buf(),
            line,
            component,
            message,
        }
    })?;
    let err = |component: Option<String>, message: String| Error::Budget {
        path: path.to_path_buf(),
        line: None,
        component,
        message,
    };
    let level = raw.level.unwrap_or(0.95);
    if !(level > 0.0 && level < 1.0) {
        return Err(err(
            None,
            format!(
                "level = {level}: write the coverage probability as a fraction in (0, 1), e.g. level = 0.95"
            ),
        ));
    }
    if raw.component.is_empty() {
        return Err(err(
            None,
            "no components: add one [[component]] table per contribution (see `calib uncertainty --help`)".into(),
        ));
    }
    let mut components = Vec::with_capacity(raw.component.len());
    for (k, c) in raw.component.into_iter().enumerate() {
        let name = c.name.clone().unwrap_or_else(|| format!("#{}", k + 1));
        components.push(component(c, &name).map_err(|m| err(Some(name.clone()), m))?);
    }
    Ok(Budget { level, components })
}

/// Validates one component; the error is the message (the caller adds the name).
fn component(c: RawComponent, name: &str) -> Result<Component, String> {
    let nonneg = |key: &str, v: f64| {
        if v.is_finite() && v >= 0.0 {
            Ok(v)
        } else {
            Err(format!("`{key} = {v}` must be a finite number ≥ 0"))
        }
    };
    let given: Vec<&str> = [
        ("u", c.u.is_some()),
        ("half_width", c.half_width.is_some()),
        ("value", c.value.is_some()),
    ]
    .into_iter()
    .filter_map(|(k, g)| g.then_some(k))
    .collect();
    const FORMS: &str = "`u = …` (a standard uncertainty), or `half_width = …` with `distribution = \"rectangular\"` (or \"triangular\", \"u-shaped\"), or `value = …` with `divisor = …`";
    if given.len() != 1 {
        return Err(if given.is_empty() {
            format!("no uncertainty given: write exactly one of {FORMS}")
        } else {
            format!(
                "gives {}: keep exactly one of {FORMS}",
                given
                    .iter()
                    .map(|k| format!("`{k}`"))
                    .collect::<Vec<_>>()
                    .join(" and ")
            )
        });
    }
    if c.distribution.is_some() && c.half_width.is_none() {
        return Err(
            "`distribution` goes with `half_width`: write `half_width = …` instead of `u`/`value`, or drop `distribution`".into(),
        );
    }
    if c.divisor.is_some() && c.value.is_none() {
        return Err(
            "`divisor` goes with `value`: write `value = …` instead of `u`/`half_width`, or drop `divisor`".into(),
        );
    }
    let standard_uncertainty = if let Some(u) = c.u {
        nonneg("u", u)?
    } else if let Some(a) = c.half_width {
        let a = nonneg("half_width", a)?;
        let Some(dist) = c.distribution.as_deref() else {
            return Err(format!(
                "`half_width` needs its distribution: add `distribution = \"rectangular\"` (or {})",
                Distribution::NAMES[1..].join(", ")
            ));
        };
        let Some(d) = Distribution::from_name(dist) else {
            return Err(format!(
                "unknown distribution \"{dist}\": write one of {}; for a normal distribution give `value` and `divisor` (the coverage factor) instead",
                Distribution::NAMES.join(", ")
            ));
        };
        a / d.divisor()
    } else {
        // `given` holds exactly "value".
        let v = nonneg("value", c.value.unwrap_or_default())?;
        let Some(div) = c.divisor else {
            return Err(
                "`value` needs `divisor = …` (e.g. 2 for a certificate's k = 2, or 2.449 = √6 for the standard deviation of a mean of 6 readings)".into(),
            );
        };
        if !(div.is_finite() && div > 0.0) {
            return Err(format!("`divisor = {div}` must be a number > 0"));
        }
        v / div
    };
    let sensitivity = match (c.sensitivity, c.estler_faces) {
        (Some(_), Some(_)) => {
            return Err(
                "gives both `sensitivity` and `estler_faces`: keep one (estler_faces = n means sensitivity = 1/n − 8/(9n²))".into(),
            );
        }
        (Some(s), None) if s.is_finite() => s,
        (Some(s), None) => return Err(format!("`sensitivity = {s}` must be a finite number")),
        (None, Some(n)) if n >= 2 => estler_sensitivity(n),
        (None, Some(n)) => {
            return Err(format!(
                "`estler_faces = {n}`: write the polygon's number of faces (≥ 2)"
            ));
        }
        (None, None) => 1.0,
    };
    let dof = match (c.dof, c.relative_uncertainty) {
        (Some(_), Some(_)) => {
            return Err(
                "gives both `dof` and `relative_uncertainty`: keep one (relative_uncertainty = r means dof = 1/(2r²))".into(),
            );
        }
        (Some(RawDof::Number(v)), None) if v >= 1.0 => v,
        (Some(RawDof::Number(v)), None) => {
            return Err(format!(
                "`dof = {v}`: degrees of freedom must be at least 1; write `dof = \"inf\"` for a value known exactly"
            ));
        }
        (Some(RawDof::Text(t)), None) if matches!(t.as_str(), "inf" | "infinity" | "∞") => {
            f64::INFINITY
        }
        (Some(RawDof::Text(t)), None) => {
            return Err(format!(
                "`dof = \"{t}\"`: write a number (dof = 5) or \"inf\""
            ));
        }
        (None, Some(r)) if r.is_finite() && r >= 0.0 => dof_from_relative_uncertainty(r),
        (None, Some(r)) => {
            return Err(format!(
                "`relative_uncertainty = {r}` must be a fraction ≥ 0, e.g. 0.10 for 10 %"
            ));
        }
        (None, None) => f64::INFINITY,
    };
    Ok(Component {
        name: name.to_string(),
        standard_uncertainty,
        sensitivity,
        dof,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Budget, Error> {
        parse_budget(text, Path::new("b.toml"))
    }

    #[test]
    fn the_three_forms_and_the_dof_rules() {
        let b = parse(
            r#"
level = 0.99
[[component]]
name = "a"
u = 0.05
dof = 5
[[component]]
name = "b"
half_width = 0.0005
distribution = "rectangular"
relative_uncertainty = 0.10
[[component]]
name = "c"
value = 0.12
divisor = 2
estler_faces = 24
[[component]]
name = "d"
u = 1
dof = "inf"
"#,
        )
        .unwrap();
        assert_eq!(b.level, 0.99);
        assert_eq!(b.components[0].dof, 5.0);
        assert!((b.components[1].standard_uncertainty - 0.0005 / 3f64.sqrt()).abs() < 1e-15);
        assert!((b.components[1].dof - 50.0).abs() < 1e-9);
        assert_eq!(b.components[2].standard_uncertainty, 0.06);
        assert!((b.components[2].sensitivity - 0.040123).abs() < 1e-6);
        assert!(b.components[2].dof.is_infinite() && b.components[3].dof.is_infinite());
    }

    #[test]
    fn errors_name_the_component_and_the_fix() {
        let e = |t: &str| parse(t).unwrap_err().to_string();
        let msg = e("[[component]]\nname = \"x\"\nhalf_width = 1\ndistribution = \"gaussian\"\n");
        assert!(
            msg.contains("component `x`") && msg.contains("unknown distribution \"gaussian\""),
            "{msg}"
        );
        let msg = e("[[component]]\nname = \"x\"\nu = 1\nvalue = 2\ndivisor = 2\n");
        assert!(msg.contains("gives `u` and `value`"), "{msg}");
        let msg = e("[[component]]\nname = \"x\"\n");
        assert!(msg.contains("no uncertainty given"), "{msg}");
        let msg = e(
            "[[component]]\nname = \"x\"\nu = 1\n\n[[component]]\nname = \"y\"\nu = 1\nsensitivty = 2\n",
        );
        assert!(
            msg.contains("b.toml: line 8: component `#2`: unknown field `sensitivty`"),
            "{msg}"
        );
        let msg = e("[[component]]\nname = \"x\"\nu = 1\ndof = \"many\"\n");
        assert!(msg.contains("write a number"), "{msg}");
        let msg = e("level = 95\n[[component]]\nu = 1\n");
        assert!(msg.contains("level = 0.95"), "{msg}");
        let msg = e("[[component]\nu = 1\n");
        assert!(msg.contains("b.toml: line 1"), "{msg}");
        assert!(e("").contains("no components"));
    }
}
