//! `calib multihead`: self-calibration of one scale read by several heads.

mod document;
mod summary;

use crate::batch::Outcome;
use crate::exit::Usage;
use crate::method::{MethodArgs, Results, finish_log, for_each_sample, in_log};
use crate::output::turn_table;
use anyhow::Context;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::multihead::{Head, Method, Multihead, MultiheadError, MultiheadOptions};
use std::path::Path;
use summary::render_summary;

/// The method, as chosen on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum MethodArg {
    /// Joint least squares of every head at once (any spacing; blind only to the orders no head
    /// pair sees; estimates the heads' angle errors).
    Joint,
    /// The published equal-division average (SelfA paper eq. 9) per set of equally spaced heads
    /// (each set blind to the multiples of its head count), sets combined order by order.
    Eda,
}

/// Self-calibrate one scale read by several heads (multi-head self-calibration, e.g. SelfA).
///
/// Record the heads' synchronized readings while the scale turns at least one whole revolution
/// (more revolutions average more noise). Name every head with its nominal angle around the
/// scale, the first being the head whose map is written: `--heads h1@0,h2@90,h3@180,h4@270` (a
/// fraction such as `h2@360/7` is accepted). Heads may read raw scale angles or angles relative
/// to their nominal place; each head's convention is recognized. The heads' small angle errors
/// are estimated (relative to the first head).
///
/// The default joint method fits every head at once and is blind only to the orders h for which
/// every head sits at a multiple of 360°/h (with heads in sets of 3, 4 and 7: multiples of 84);
/// `--method eda` applies the published average per set of equally spaced heads (`--sets`, or
/// inferred from the angles), blind to the multiples of each set's head count.
///
/// Writes DIR/<first head>.csv (the scale's error as the first head reads it, as a function of
/// its reading: angle_deg, error_arcsec, correction_arcsec; correction = −error, zero mean) and
/// DIR/report.json (head angle errors, blind orders, residual) and DIR/report.html, and prints a
/// summary. With several logs, each log's files go to DIR/<log stem>/ and DIR/summary.json holds
/// every log's verdict.
///
/// Channels on separate topics are aligned on the stamps of the first head (see --time, --max-gap).
///
/// Exit status: 0 all logs calibrated and passed the gates, 1 a log could not be calibrated
/// (bad or insufficient data), 2 bad usage, 3 a gate failed (outputs written all the same).
#[derive(Debug, clap::Args, PartialEq)]
#[command(after_long_help = crate::input::channel_names())]
pub struct Args {
    /// The heads as NAME@DEG (nominal angle in degrees), comma-separated or repeated; the first
    /// is the head whose map is written.
    #[arg(long, required = true, value_delimiter = ',', value_name = "NAME@DEG")]
    pub heads: Vec<String>,
    /// The method.
    #[arg(long, value_enum, default_value_t = MethodArg::Joint)]
    pub method: MethodArg,
    /// One EDA set: comma-separated names of heads equally spaced with the first head (e.g.
    /// `--sets h1,h5,h9 --sets h1,h3,h7,h11`); repeat for several sets. Default: every maximal
    /// set of equally spaced heads found in --heads. Only with --method eda.
    #[arg(long = "sets", value_name = "NAME,NAME,...")]
    pub sets: Vec<String>,
    /// Highest harmonic order fitted (default: 40 % of the samples per revolution, at most a
    /// quarter of the bins the readings fill, and 2000).
    #[arg(long)]
    pub max_order: Option<usize>,
    /// Points of the output table (default: enough for linear interpolation to 0.01″, ≥ 3600).
    #[arg(long)]
    pub points: Option<usize>,
    /// Orders whose observability (0 blind … 1 as seen by equally spaced heads) is below this
    /// are left out of the map (joint method).
    #[arg(long, default_value_t = 0.01)]
    pub min_observability: f64,
    /// Logs, output, unit, output form, gates, timing.
    #[command(flatten)]
    pub common: MethodArgs,
}

/// One `NAME@DEG` of `--heads`.
fn parse_head(spec: &str) -> Result<Head, Usage> {
    let bad = || {
        Usage(format!(
            "--heads: `{spec}` is not NAME@DEG (a channel name and its nominal angle in degrees, e.g. h2@90 or h2@360/7)"
        ))
    };
    let (name, angle) = spec.rsplit_once('@').ok_or_else(bad)?;
    let (name, angle) = (name.trim(), angle.trim());
    if name.is_empty() {
        return Err(bad());
    }
    let number = |s: &str| s.trim().parse::<f64>().ok().filter(|v| v.is_finite());
    let deg = match angle.split_once('/') {
        Some((num, den)) => number(num)
            .zip(number(den).filter(|d| *d != 0.0))
            .map(|(n, d)| n / d),
        None => number(angle),
    }
    .ok_or_else(bad)?;
    Ok(Head {
        name: name.to_string(),
        nominal: deg.to_radians(),
    })
}

/// The heads of `--heads`, checked for duplicates.
fn parse_heads(specs: &[String]) -> Result<Vec<Head>, Usage> {
    let heads = specs
        .iter()
        .map(|s| parse_head(s))
        .collect::<Result<Vec<_>, _>>()?;
    for (i, h) in heads.iter().enumerate() {
        if heads[..i].iter().any(|o| o.name == h.name) {
            return Err(Usage(format!(
                "--heads names `{}` twice; name each head once",
                h.name
            )));
        }
    }
    if heads.len() < 2 {
        return Err(Usage(format!(
            "--heads names {} head(s); a multi-head calibration needs at least 2",
            heads.len()
        )));
    }
    Ok(heads)
}

/// The sets of `--sets` as indices into the heads.
fn parse_sets(specs: &[String], heads: &[Head]) -> Result<Vec<Vec<usize>>, Usage> {
    specs
        .iter()
        .map(|spec| {
            spec.split(',')
                .map(|name| {
                    let name = name.trim();
                    heads.iter().position(|h| h.name == name).ok_or_else(|| {
                        Usage(format!(
                            "--sets {spec}: `{name}` is not one of the heads in --heads ({})",
                            heads
                                .iter()
                                .map(|h| h.name.as_str())
                                .collect::<Vec<_>>()
                                .join(", ")
                        ))
                    })
                })
                .collect()
        })
        .collect()
}

/// Runs `calib multihead`.
impl super::Method for Args {
    const NAME: &'static str = "multihead";
    type Prepared = (Vec<Head>, MultiheadOptions);

    fn runs(&self) -> super::Runs<'_> {
        self.common.runs()
    }

    fn prepare(&self) -> anyhow::Result<Self::Prepared> {
        prepare(self)
    }

    fn calibrate(
        &self,
        (heads, opts): &Self::Prepared,
        log: &Path,
        out: &Path,
    ) -> anyhow::Result<Outcome> {
        calibrate(self, heads, opts, log, out)
    }
}

/// Checks the arguments before any log is read; the heads and the options every log's run
/// shares.
fn prepare(args: &Args) -> anyhow::Result<(Vec<Head>, MultiheadOptions)> {
    let heads = parse_heads(&args.heads)?;
    if !args.sets.is_empty() && args.method != MethodArg::Eda {
        return Err(Usage(
            "--sets is for --method eda; the joint method uses every head at once".into(),
        )
        .into());
    }
    let sets = parse_sets(&args.sets, &heads)?;
    if let Some(h) = args.max_order {
        crate::input::check_count("--max-order", h, 1, None)?;
    }
    crate::input::check_points(args.points)?;
    crate::input::check_fraction("--min-observability", args.min_observability)?;
    let opts = MultiheadOptions {
        method: match args.method {
            MethodArg::Joint => Method::Joint,
            MethodArg::Eda => Method::Eda,
        },
        max_order: args.max_order,
        min_observability: args.min_observability,
        points: args.points,
        sets: (!sets.is_empty()).then_some(sets),
        ..MultiheadOptions::default()
    };
    // Head and set problems concern the command line, whatever the log holds.
    Multihead::new(heads.clone(), opts.clone()).map_err(|e| Usage(e.to_string()))?;
    Ok((heads, opts))
}

/// Calibrates one log into the folder `out`.
fn calibrate(
    args: &Args,
    heads: &[Head],
    opts: &MultiheadOptions,
    log: &Path,
    out: &Path,
) -> anyhow::Result<Outcome> {
    let mut mh = Multihead::new(heads.to_vec(), opts.clone()).map_err(|e| Usage(e.to_string()))?;
    let names: Vec<&str> = heads.iter().map(|h| h.name.as_str()).collect();
    let reader = args.common.open(log, &names)?;
    // The sample's values are the heads' readings, in the heads' order.
    let reader = for_each_sample(log, reader, |s| {
        mh.push(s.values);
    })?;
    let cal = mh.finish().map_err(|e| match e {
        MultiheadError::NoWholeTurn { turn, cause } => {
            crate::input::no_whole_turn(*cause, &format!("head `{}`", heads[0].name), &turn)
        }
        e => anyhow::Error::new(e),
    });
    let cal = cal
        .with_context(|| {
            format!(
                "{}: heads {}",
                log.display(),
                heads
                    .iter()
                    .map(|h| h.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        })
        .map_err(|e| in_log(e, &reader, log))?;
    let first = &heads[0].name;
    let results = Results {
        section: cal.report_section(heads),
        tables: vec![turn_table(
            first,
            &cal.map,
            Some(cal.uncertainty.u.as_slice()),
        )?],
        channels: vec![first.clone()],
        residual_rms_arcsec: cal.residual_rms.map(|r| r * ARCSEC_PER_RAD),
        document: Box::new(|report| document::document(first, &cal, report)),
        summary: Box::new(|report| render_summary(args, out, heads, &cal, report)),
    };
    finish_log(&reader, log, out, args.common.presentation(), results)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn head_specs_parse_or_say_what_is_wrong() {
        let h = parse_head("h2@90").unwrap();
        assert_eq!(h.name, "h2");
        assert!((h.nominal - 90f64.to_radians()).abs() < 1e-15);
        let h = parse_head("arm/joint@3@360/7").unwrap();
        assert_eq!(h.name, "arm/joint@3");
        assert!((h.nominal.to_degrees() - 360.0 / 7.0).abs() < 1e-12);
        assert!((parse_head(" h3 @ -45.5 ").unwrap().nominal.to_degrees() + 45.5).abs() < 1e-12);
        for bad in ["h2", "@90", "h2@", "h2@abc", "h2@1/0", "h2@inf", "h2@1/2/3"] {
            let err = parse_head(bad).unwrap_err().to_string();
            assert!(err.contains("NAME@DEG"), "{bad}: {err}");
        }
        let twice = parse_heads(&["a@0".into(), "b@90".into(), "a@180".into()]).unwrap_err();
        assert!(twice.to_string().contains("`a` twice"), "{twice}");
        assert!(parse_heads(&["a@0".into()]).is_err());
    }

    #[test]
    fn sets_name_heads_of_heads() {
        let heads = parse_heads(&["a@0".into(), "b@120".into(), "c@240".into()]).unwrap();
        assert_eq!(
            parse_sets(&["a,b,c".into()], &heads).unwrap(),
            [vec![0, 1, 2]]
        );
        let err = parse_sets(&["a,x".into()], &heads).unwrap_err().to_string();
        assert!(
            err.contains("`x` is not one of the heads") && err.contains("a, b, c"),
            "{err}"
        );
    }

    #[test]
    fn heads_split_on_commas_and_each_sets_is_one_set() {
        use clap::Parser;
        let cli = crate::cli::Cli::try_parse_from([
            "calib",
            "multihead",
            "run.mcap",
            "--heads",
            "a@0,b@90",
            "--heads",
            "c@180",
            "--method",
            "eda",
            "--sets",
            "a,c",
            "--sets",
            "a,b,c",
        ])
        .unwrap();
        let crate::cli::Command::Multihead(args) = cli.command else {
            panic!("not multihead");
        };
        assert_eq!(args.heads, ["a@0", "b@90", "c@180"]);
        assert_eq!(args.sets, ["a,c", "a,b,c"]);
        assert_eq!(args.method, MethodArg::Eda);
        assert!(crate::cli::Cli::try_parse_from(["calib", "multihead", "run.mcap"]).is_err());
    }
}
