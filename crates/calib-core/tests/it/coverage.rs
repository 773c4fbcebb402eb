//! Monte Carlo check of the standard uncertainties `u` of the self-calibration tables: for each
//! bundled scenario and several seeds (new noise and quantization phase each time, the same
//! errors), the fraction of table points with |map − truth| ≤ 2u (near 95 % for an honest
//! standard uncertainty of a normal error) and ≤ u (near 68 %), and the median u.
//!
//! `#[ignore]`d (about two minutes in all): `cargo test -p calib-core --test it coverage:: --
//! --ignored --nocapture` prints the tables quoted in the README's accuracy section — the joint
//! methods', the paper method's (`coverage_of_the_paper_method_over_seeds`, 5 s) — and the check
//! of the joint method's `u` on `csrr72.toml` over 16 seeds.

use calib_core::ErrorMap;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::csrr::{Csrr, CsrrOptions, Method as CsrrMethod};
use calib_core::multihead::{Head, Method, Multihead, MultiheadOptions};
use calib_core::simulate::Scenario;
use calib_core::tdr::{Tdr, TdrOptions};
use calib_core::uncertainty::MapUncertainty;

const SEEDS: [u64; 5] = [1, 2, 3, 4, 5];

fn scenario(file: &str, seed: u64) -> Scenario {
    let path = format!(
        "{}/../../testdata/scenarios/{file}",
        env!("CARGO_MANIFEST_DIR")
    );
    let mut s: Scenario = toml::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    s.seed = seed;
    s
}

fn truth(s: &Scenario, name: &str, points: usize) -> ErrorMap {
    s.truth(points)
        .unwrap()
        .into_iter()
        .find(|(n, _)| n == name)
        .unwrap()
        .1
}

/// Points within `u` and within `2u`, and the points counted; the u values for the median.
#[derive(Default)]
struct Tally {
    within_u: usize,
    within_2u: usize,
    points: usize,
    u: Vec<f64>,
    worst: f64,
}

impl Tally {
    fn add(&mut self, map: &ErrorMap, u: &MapUncertainty, truth: &ErrorMap) {
        let diff = map.minus(truth);
        for (d, u) in diff.values().iter().zip(&u.u) {
            self.within_u += usize::from(d.abs() <= *u);
            self.within_2u += usize::from(d.abs() <= 2.0 * u);
        }
        self.points += map.len();
        self.u.push(u.median());
        self.worst = self.worst.max(diff.max_abs_arcsec());
    }

    fn row(&mut self, name: &str) -> (f64, f64) {
        self.u.sort_by(f64::total_cmp);
        let median = self.u[self.u.len() / 2] * ARCSEC_PER_RAD;
        let f2 = self.within_2u as f64 / self.points as f64;
        println!(
            "| {name} | {} | {:.1} % | {:.1} % | {median:.4}″ | {:.4}″ |",
            SEEDS.len(),
            100.0 * self.within_u as f64 / self.points as f64,
            100.0 * f2,
            self.worst
        );
        (f2, median)
    }
}

/// Sensor A's and B's tallies of `calib csrr --method METHOD` on `file` over the seeds.
fn csrr_tallies(file: &str, method: CsrrMethod) -> (Tally, Tally) {
    let (mut ta, mut tb) = (Tally::default(), Tally::default());
    for seed in SEEDS {
        let s = scenario(file, seed);
        let channels = s.channels();
        let ia = channels.iter().position(|c| c.name == "a").unwrap();
        let ib = channels.iter().position(|c| c.name == "b").unwrap();
        let mut csrr = Csrr::new(CsrrOptions {
            method,
            ..CsrrOptions::default()
        });
        for x in s.samples().unwrap() {
            csrr.push(x.t, x.values[ia], x.values[ib], None);
        }
        let cal = csrr.finish().unwrap();
        let (ua, ub) = cal.uncertainty.as_ref().unwrap();
        ta.add(&cal.a, ua, &truth(&s, "a", cal.a.len()));
        tb.add(&cal.b, ub, &truth(&s, "b", cal.b.len()));
    }
    (ta, tb)
}

#[test]
#[ignore = "Monte Carlo over seeds, about a minute"]
fn coverage_of_u_over_seeds() {
    println!("| scenario (map) | seeds | ≤ u | ≤ 2u | median u | max \\|map − truth\\| |");
    println!("|---|---|---|---|---|---|");
    let mut rows = Vec::new();
    for file in ["csrr72.toml", "csrr84.toml", "csrr90.toml"] {
        let (mut ta, mut tb) = csrr_tallies(file, CsrrMethod::Joint);
        rows.push(ta.row(&format!("csrr `{file}` (a)")));
        rows.push(tb.row(&format!("csrr `{file}` (b)")));
    }
    for file in [
        "spindown.toml",
        "spindown-bearing.toml",
        "spindown-wide.toml",
        "spindown-drag.toml",
    ] {
        let mut t = Tally::default();
        for seed in SEEDS {
            let s = scenario(file, seed);
            let mut tdr = Tdr::new(TdrOptions::default());
            for x in s.samples().unwrap() {
                tdr.push(x.t, x.values[0]);
            }
            let cal = tdr.finish().unwrap();
            t.add(&cal.map, &cal.uncertainty, &truth(&s, "enc", cal.map.len()));
        }
        rows.push(t.row(&format!("tdr `{file}`")));
    }
    for method in [Method::Joint, Method::Eda] {
        let mut t = Tally::default();
        for seed in SEEDS {
            let s = scenario("multihead.toml", seed);
            let heads = s
                .sensors
                .iter()
                .map(|h| Head {
                    name: h.name.clone(),
                    nominal: h.head_deg.unwrap().to_radians(),
                })
                .collect();
            let opts = MultiheadOptions {
                method,
                ..MultiheadOptions::default()
            };
            let mut mh = Multihead::new(heads, opts).unwrap();
            for x in s.samples().unwrap() {
                mh.push(&x.values);
            }
            let cal = mh.finish().unwrap();
            let first = &s.sensors[0].name;
            t.add(&cal.map, &cal.uncertainty, &truth(&s, first, cal.map.len()));
        }
        rows.push(t.row(&format!("multihead `multihead.toml` ({method:?})")));
    }
    // Over all seeds, 2u covers 90–99.9 % of the points on every map (the range for one
    // run; near 95 % is the target), and u stays small.
    for (f2, median) in rows {
        assert!((0.90..=0.999).contains(&f2), "{f2}");
        assert!(median <= 0.1, "{median}″");
    }
}

/// The paper method (`calib csrr --method paper`): one point per session, linear interpolation
/// between them. Its `u` is mostly a bound on deterministic errors (the interpolation between
/// the points, ε_θ's bias) taken as rectangular or random-phase distributions, so `2u` may cover
/// more than 95 %; the bar is at least 90 %. On the 5-session runs the paper method cannot
/// resolve the sensors' orders at all: its `u` says so (tens of arcseconds).
#[test]
#[ignore = "Monte Carlo over seeds, about half a minute"]
fn coverage_of_the_paper_method_over_seeds() {
    println!("| scenario (map) | seeds | ≤ u | ≤ 2u | median u | max \\|map − truth\\| |");
    println!("|---|---|---|---|---|---|");
    let mut rows = Vec::new();
    for file in [
        "paper40.toml",
        "paper40-shared.toml",
        "csrr72.toml",
        "csrr84.toml",
        "csrr90.toml",
    ] {
        let (mut ta, mut tb) = csrr_tallies(file, CsrrMethod::Paper);
        rows.push(ta.row(&format!("csrr paper `{file}` (a)")));
        rows.push(tb.row(&format!("csrr paper `{file}` (b)")));
    }
    for (f2, _) in rows {
        assert!(f2 >= 0.90, "{f2}");
    }
}

/// Whether the joint method's `u` misses a term on `csrr72.toml`, whose sensor b covers only
/// 90.8 % within `2u` on its own seed. Its map error is a sum over the ~6 kept orders of
/// coefficient errors of variance `v_h`, so over the circle `E[rms(map − truth)²] = Σ v_h = u_fit²`
/// — for an honest `u` the ratio `(rms error / rms u)²` has mean 1 over seeds, while one run's
/// ratio is a χ² of ~12 degrees of freedom over 12 (standard deviation ≈ 0.4) and its fraction
/// within `2u` varies widely from run to run. Over 16 seeds the mean ratio is measured 0.98 (a)
/// and 0.90 (b), and single runs cover 84–100 % (a) and 83–100 % (b) within `2u`: no term is
/// missing; 90.8 % on one seed is that spread. The bar, 0.7–1.3, is ±3 standard deviations of
/// the mean of 16 (≈ 0.1 each).
#[test]
#[ignore = "Monte Carlo over 16 seeds, about 20 s"]
fn joint_u_on_csrr72_is_honest_on_average_over_seeds() {
    let seeds = 1..=16u64;
    let mut ratio = [0.0; 2];
    for seed in seeds.clone() {
        let s = scenario("csrr72.toml", seed);
        let channels = s.channels();
        let ia = channels.iter().position(|c| c.name == "a").unwrap();
        let ib = channels.iter().position(|c| c.name == "b").unwrap();
        let mut csrr = Csrr::new(CsrrOptions::default());
        for x in s.samples().unwrap() {
            csrr.push(x.t, x.values[ia], x.values[ib], None);
        }
        let cal = csrr.finish().unwrap();
        let (ua, ub) = cal.uncertainty.as_ref().unwrap();
        let mut line = format!("seed {seed:2}:");
        for (i, (name, map, u)) in [("a", &cal.a, ua), ("b", &cal.b, ub)]
            .into_iter()
            .enumerate()
        {
            let diff = map.minus(&truth(&s, name, map.len()));
            let inside = diff
                .values()
                .iter()
                .zip(&u.u)
                .filter(|(d, u)| d.abs() <= 2.0 * **u)
                .count() as f64
                / map.len() as f64;
            let r = (diff.rms() / u.rms()).powi(2);
            ratio[i] += r;
            line += &format!(
                "  {name}: ≤ 2u {:.1} %, (rms error / rms u)² {r:.3}",
                100.0 * inside
            );
        }
        println!("{line}");
    }
    let n = seeds.count() as f64;
    let mean = [ratio[0] / n, ratio[1] / n];
    println!(
        "mean (rms error / rms u)²: a {:.3}, b {:.3}",
        mean[0], mean[1]
    );
    for m in mean {
        assert!((0.7..=1.3).contains(&m), "{m}");
    }
}
