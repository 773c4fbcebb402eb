//! The run simulator against its own truth: fixed seeds, explicit tolerances with reasons.

use calib_core::angle::{ARCSEC_PER_RAD, wrap_pi};
use calib_core::simulate::{Mount, Scenario, ScenarioError};
use std::f64::consts::TAU;

const SCENARIOS: [(&str, &str); 8] = [
    (
        "csrr72",
        include_str!("../../../../testdata/scenarios/csrr72.toml"),
    ),
    (
        "csrr84",
        include_str!("../../../../testdata/scenarios/csrr84.toml"),
    ),
    (
        "csrr90",
        include_str!("../../../../testdata/scenarios/csrr90.toml"),
    ),
    (
        "quick",
        include_str!("../../../../testdata/scenarios/quick.toml"),
    ),
    (
        "multihead",
        include_str!("../../../../testdata/scenarios/multihead.toml"),
    ),
    (
        "spindown",
        include_str!("../../../../testdata/scenarios/spindown.toml"),
    ),
    (
        "spindown-bearing",
        include_str!("../../../../testdata/scenarios/spindown-bearing.toml"),
    ),
    (
        "joint",
        include_str!("../../../../testdata/scenarios/joint.toml"),
    ),
];

fn scenario(name: &str) -> Scenario {
    let text = SCENARIOS.iter().find(|(n, _)| *n == name).unwrap().1;
    toml::from_str(text).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// The scenario with every channel's noise and quantization off.
fn noiseless(mut s: Scenario) -> Scenario {
    for sensor in &mut s.sensors {
        sensor.noise_arcsec = 0.0;
        sensor.quantization_arcsec = 0.0;
    }
    s
}

fn arcsec(rad: f64) -> f64 {
    rad * ARCSEC_PER_RAD
}

#[test]
fn every_testdata_scenario_parses_validates_and_round_trips() {
    for (name, text) in SCENARIOS {
        let s: Scenario = toml::from_str(text).unwrap_or_else(|e| panic!("{name}: {e}"));
        s.validate().unwrap_or_else(|e| panic!("{name}: {e}"));
        let back: Scenario = toml::from_str(&toml::to_string(&s).unwrap()).unwrap();
        assert_eq!(back, s, "{name}");
    }
}

#[test]
fn testdata_scenarios_have_the_stated_sizes_and_error_ranges() {
    // (scenario, channel, peak-to-peak range in arcsec) as the files' comments promise.
    let cases = [
        ("csrr72", "a", 60.0, 100.0),    // ±37″ class (paper Table I)
        ("csrr72", "ref", 1.0, 2.5),     // ±1″ reference
        ("csrr84", "a", 1300.0, 1600.0), // ±680″
        ("csrr84", "b", 1300.0, 1600.0),
        ("csrr90", "a", 450.0, 560.0), // ±250″
        ("csrr90", "b", 400.0, 560.0),
        ("quick", "a", 30.0, 70.0),
        ("multihead", "h1", 2.2, 3.2), // ±1.4″
    ];
    for (file, channel, lo, hi) in cases {
        let truths = scenario(file).sensor_truths().unwrap();
        let t = truths.iter().find(|t| t.name() == channel).unwrap();
        let pp = t.peak_to_peak_arcsec();
        assert!((lo..hi).contains(&pp), "{file}/{channel}: {pp}″");
    }
    let quick = scenario("quick").samples().unwrap();
    assert!((3000..4000).contains(&quick.len()), "{}", quick.len());
    // 5 × (3 revolutions at 6 s + 2 ramps + pause) + 4 × (turn + pause) + lead-in pause.
    let csrr72 = scenario("csrr72").samples().unwrap();
    assert!((csrr72.duration_s() - (5.0 * 21.0 + 4.0 * 3.0 + 1.0)).abs() < 1e-9);
    assert_eq!(scenario("multihead").channels().len(), 12);
}

#[test]
fn readings_minus_truth_at_the_reading_is_the_injected_error() {
    // The ±680″ sensors are the hardest inversion; the heads check the shifted-scale model.
    for (file, take) in [("csrr84", 30_000), ("multihead", 5_000)] {
        let mut s = noiseless(scenario(file));
        s.time_jitter_s = 1e-4;
        let truths = s.sensor_truths().unwrap();
        for st in s.samples().unwrap().with_truth().step_by(7).take(take) {
            for ((r, th), truth) in st.sample.values.iter().zip(&st.true_angles).zip(&truths) {
                let injected = wrap_pi(r - th);
                let recovered = truth.error_at_reading(*r);
                // Newton stops at rounding level; 1e-6″ leaves a wide margin above it.
                let d = arcsec(injected - recovered).abs();
                assert!(
                    d < 1e-6,
                    "{file}/{}: {d}″ at t = {}",
                    truth.name(),
                    st.sample.t
                );
            }
        }
    }
}

#[test]
fn truth_maps_are_the_reading_domain_errors_on_the_grid() {
    let s = scenario("csrr84");
    let maps = s.truth(3600).unwrap();
    let truths = s.sensor_truths().unwrap();
    for ((name, map), t) in maps.iter().zip(&truths) {
        assert_eq!(name, t.name());
        let values: Vec<f64> = (0..3600)
            .map(|i| t.error_at_reading(map.grid_angle(i)))
            .collect();
        let mean = values.iter().sum::<f64>() / 3600.0;
        // ∫ e(θ(r)) dr = ∫ e(θ)(1 + e′(θ)) dθ = 0 for a sum of harmonics: the grid mean is ~0,
        // limited by the grid's quadrature of the high orders the inversion creates.
        assert!(arcsec(mean).abs() < 1e-3, "{name}: mean {}″", arcsec(mean));
        for (v, m) in values.iter().zip(map.values()) {
            assert!(arcsec(v - mean - m).abs() < 1e-9);
        }
    }
    // Far from "e evaluated at the reading": at ±680″ the difference reaches tens of arcsec.
    let a = &truths[0];
    let worst = (0..3600)
        .map(|i| {
            let r = TAU * i as f64 / 3600.0;
            arcsec(a.error_at_reading(r) - a.error_at_true(r)).abs()
        })
        .fold(0.0, f64::max);
    assert!(worst > 10.0, "{worst}");
    assert!(matches!(
        s.truth(0),
        Err(ScenarioError::InvalidValue { .. })
    ));
}

#[test]
fn sessions_hold_the_relative_rotation_and_whole_revolutions() {
    let s = noiseless(scenario("quick"));
    let deltas = s.procedure.relative_deg.clone();
    let mut per_session = vec![(0usize, 0.0f64); deltas.len()];
    for st in s.samples().unwrap().with_truth() {
        let (a, b) = (st.sample.values[0], st.sample.values[1]);
        assert_eq!(st.sample.session, st.session, "quick.toml marks sessions");
        if let Some(k) = st.session {
            let k = k as usize;
            // Exactly: θ_A − θ_B = Δ_k throughout the session.
            assert!((st.relative.to_degrees() - deltas[k]).abs() < 1e-12);
            assert!((st.true_angles[0] - st.true_angles[1] - st.relative).abs() < 1e-12);
            per_session[k].0 += 1;
            per_session[k].1 += wrap_pi(a - b);
        }
    }
    for (k, (n, sum)) in per_session.iter().enumerate() {
        // 2 revolutions at 1 rev/s, 200 Hz.
        assert_eq!(*n, 400, "session {k}");
        // Readings differ by Δ_k + e_a − e_b; over whole revolutions the errors average out up
        // to the 0.5 % speed ripple's weighting of ~20″ errors: well below 0.2″.
        let mean_deg = (sum / *n as f64).to_degrees();
        assert!(
            ((mean_deg - deltas[k]) * 3600.0).abs() < 0.2,
            "session {k}: {mean_deg}"
        );
    }
    // Without marks the samples carry no session.
    let mut unmarked = s.clone();
    unmarked.mark_sessions = false;
    assert!(unmarked.samples().unwrap().all(|x| x.session.is_none()));
}

/// A single perfect sensor on the shaft, one session of whole revolutions, readings
/// accumulated, marks on.
fn perfect_shaft() -> Scenario {
    toml::from_str(
        r#"
        wrap = false
        mark_sessions = true
        [[sensor]]
        name = "enc"
        [procedure]
        relative_deg = [0.0]
        revolutions = 2.0
        "#,
    )
    .unwrap()
}

/// Amplitude (arcsec) of order `h` of the shaft's deviation from uniform motion over the marked
/// constant-speed samples, by a DFT over their whole revolutions.
fn modulation_amplitude(s: &Scenario, h: f64) -> f64 {
    let omega = s.speed_rpm * TAU / 60.0;
    let (mut re, mut im, mut n) = (0.0, 0.0, 0.0);
    for x in s.samples().unwrap().filter(|x| x.session.is_some()) {
        // θ − ωt = φ0 − ωt0 + ε_θ(φ): the constant has no order-h content over whole turns.
        let d = x.values[0] - omega * x.t;
        re += d * (h * omega * x.t).cos();
        im += d * (h * omega * x.t).sin();
        n += 1.0;
    }
    arcsec(2.0 * re.hypot(im) / n)
}

#[test]
fn speed_modulation_amplitude_is_recovered() {
    let mut s = perfect_shaft();
    s.speed.harmonics = vec![calib_core::simulate::HarmonicSpec {
        order: 3,
        amplitude_arcsec: 100.0,
        phase_deg: 30.0,
    }];
    // The DFT samples ε_θ at φ = ωt (exact sample grid over whole revolutions), but ε_θ is a
    // function of φ, not θ: no approximation — expect float rounding only.
    let a3 = modulation_amplitude(&s, 3.0);
    assert!((a3 - 100.0).abs() < 1e-6, "{a3}");
    assert!(modulation_amplitude(&s, 5.0) < 1e-6);
    // ±1 % speed ripple once per revolution = order-1 modulation of 0.01 rad.
    let mut s = perfect_shaft();
    s.speed.variation_percent = 1.0;
    let a1 = modulation_amplitude(&s, 1.0);
    assert!((a1 - 0.01 * ARCSEC_PER_RAD).abs() < 1e-6, "{a1}");
}

#[test]
fn quantization_step_and_noise_level_are_visible() {
    let mut s = perfect_shaft();
    // At 10 r/min and 400 Hz the shaft moves exactly 540″ per sample and would sit on the 1″
    // grid at every sample; an odd speed makes the rounding error sweep its range.
    s.speed_rpm = 9.87;
    s.sensors[0].quantization_arcsec = 1.0;
    let q = 1.0 / ARCSEC_PER_RAD;
    let (mut sum2, mut n) = (0.0, 0.0);
    for st in s.samples().unwrap().with_truth() {
        let r = st.sample.values[0];
        assert!(
            (r / q - (r / q).round()).abs() < 1e-6,
            "reading not on the 1″ grid"
        );
        let d = arcsec(r - st.true_angles[0]);
        assert!(d.abs() <= 0.5 + 1e-6, "{d}");
        if st.sample.session.is_some() {
            sum2 += d * d;
            n += 1.0;
        }
    }
    // Moving readings quantize to a uniform error on ±q/2: RMS q/√12 ≈ 0.289″; 4800 samples
    // estimate it within a few percent.
    let rms = (sum2 / n).sqrt();
    assert!((rms - 12f64.sqrt().recip()).abs() < 0.02, "{rms}");

    let mut s = perfect_shaft();
    s.sensors[0].noise_arcsec = 0.5;
    let d: Vec<f64> = s
        .samples()
        .unwrap()
        .with_truth()
        .map(|st| arcsec(st.sample.values[0] - st.true_angles[0]))
        .collect();
    let sd = (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt();
    // ~6000 samples: relative standard error of σ ≈ 1/√(2n) ≈ 0.9 %; 5 % bound.
    assert!((sd - 0.5).abs() < 0.025, "{sd}");
}

#[test]
fn output_is_deterministic_for_a_seed() {
    let s = scenario("quick");
    let first: Vec<_> = s.samples().unwrap().collect();
    let again: Vec<_> = s.samples().unwrap().collect();
    assert_eq!(first, again);
    let mut other = s.clone();
    other.seed += 1;
    let different: Vec<_> = other.samples().unwrap().collect();
    assert_ne!(first, different);
    // Stamps are exact multiples of the sample period, with or without jitter.
    let mut jittered = s.clone();
    jittered.time_jitter_s = 1e-4;
    for (k, x) in jittered.samples().unwrap().enumerate() {
        assert_eq!(x.t, k as f64 / s.rate_hz);
    }
    // Adding a channel leaves the others' noise unchanged (one noise stream per channel).
    let mut more = s.clone();
    more.sensors.push(more.sensors[0].clone());
    more.sensors[2].name = "c".into();
    for (x, y) in first.iter().zip(more.samples().unwrap()) {
        assert_eq!(x.values[..], y.values[..2]);
    }
}

#[test]
fn heads_share_the_scale_and_show_their_angle_errors() {
    let s = noiseless(scenario("multihead"));
    let truths = s.sensor_truths().unwrap();
    let h1 = &truths[0];
    let n = s.sensors.len();
    let (mut sums, mut count) = (vec![0.0; n], 0.0);
    for x in s.samples().unwrap() {
        if x.t < 2.0 || x.t >= 20.0 {
            continue; // the 3 whole constant-speed revolutions: 2 s of pause and ramp, then 18 s
        }
        for (j, r) in x.values.iter().enumerate() {
            // Each head reports relative to its nominal angle: all read ≈ θ.
            sums[j] += wrap_pi(r - x.values[0]);
        }
        count += 1.0;
    }
    for (j, t) in truths.iter().enumerate() {
        let delta = arcsec(t.head_angle_error().unwrap());
        assert_eq!(delta, s.sensors[j].head_error_arcsec.unwrap());
        // Readings of head j minus head 1 average to δ_j over whole revolutions: the scale error
        // averages out, up to the 1 % speed ripple's weighting of a ±1.4″ error (< 0.03″).
        let mean = arcsec(sums[j] / count);
        assert!(
            (mean - delta).abs() < 0.03,
            "{}: {mean} vs {delta}",
            t.name()
        );
    }
    // Head 1 at 0° reads the scale itself: its map is the scale's.
    let scale_at = |x: f64| {
        s.scales[0]
            .harmonics
            .iter()
            .map(|h| h.amplitude_arcsec * (f64::from(h.order) * x + h.phase_deg.to_radians()).cos())
            .sum::<f64>()
    };
    for k in 0..50 {
        let x = k as f64 * 0.1;
        assert!((arcsec(h1.error_at_true(x)) - scale_at(x)).abs() < 1e-9);
    }
    assert_eq!(s.sensors.iter().filter(|x| x.mount.is_some()).count(), 0);
    assert_eq!(s.scales[0].mount, Mount::B);
}

fn invalid(text: &str) -> String {
    match toml::from_str::<Scenario>(text) {
        Err(e) => e.to_string(),
        Ok(s) => s.validate().unwrap_err().to_string(),
    }
}

#[test]
fn invalid_scenarios_are_rejected_with_the_field_named() {
    let base = "[procedure]\nrelative_deg = [0.0]\n";
    let cases = [
        // (scenario text, what the message must contain)
        (format!("rate_hz = -400.0\n[[sensor]]\nname = \"a\"\n{base}"), "rate_hz = -400: must be > 0"),
        (format!("speed_rpm = 0.0\n[[sensor]]\nname = \"a\"\n{base}"), "speed_rpm"),
        (format!("[[sensor]]\nname = \"a\"\nmount = \"c\"\n{base}"), "unknown variant `c`"),
        (format!("[[sensor]]\nname = \"a\"\nnoise = 1.0\n{base}"), "unknown field `noise`"),
        ("[[sensor]]\nname = \"a\"\n".to_string(), "no sessions"),
        (base.to_string(), "no [[sensor]]"),
        (format!("[[sensor]]\nname = \"a\"\n[[sensor]]\nname = \"a\"\n{base}"), "`a` is used twice"),
        (format!("[[sensor]]\nname = \"\"\n{base}"), "empty name"),
        (format!("[[sensor]]\nname = \"h\"\nscale = \"disc\"\n{base}"), "reads scale `disc`, which no [[scale]] defines (defined: none)"),
        (format!("[[sensor]]\nname = \"h\"\nhead_deg = 90.0\n{base}"), "need `scale`"),
        (format!("[[scale]]\nname = \"d\"\n[[sensor]]\nname = \"h\"\nscale = \"d\"\nmount = \"a\"\n{base}"), "`mount` is not allowed with `scale`"),
        (format!("[[sensor]]\nname = \"a\"\nnoise_arcsec = -1.0\n{base}"), "sensor `a` noise_arcsec = -1"),
        (format!("[[sensor]]\nname = \"a\"\nharmonics = [{{ order = 0, amplitude_arcsec = 1.0 }}]\n{base}"), "sensor `a` harmonic 1 order = 0"),
        // 1000 × 300″ = 1.45 rad/rad: the reading would not determine the angle.
        (format!("[[sensor]]\nname = \"a\"\nharmonics = [{{ order = 1000, amplitude_arcsec = 300.0 }}]\n{base}"), "sensor `a`: Σ order·|amplitude| = 1.454"),
        (format!("[speed]\nvariation_percent = 150.0\n[[sensor]]\nname = \"a\"\n{base}"), "speed: Σ order"),
        ("[[sensor]]\nname = \"a\"\n[procedure]\nrelative_deg = [0.0]\n[[procedure.sessions]]\nrelative_deg = 1.0\n".to_string(), "not both"),
        ("[[sensor]]\nname = \"a\"\n[procedure]\nrelative_deg = [0.0]\nrevolutions = -1.0\n".to_string(), "procedure.revolutions"),
        ("[[sensor]]\nname = \"a\"\n[procedure]\nsessions = [{ relative_deg = 1.0, revolutions = 0.0 }]\n".to_string(), "procedure session 1 revolutions = 0"),
    ];
    for (text, want) in cases {
        let msg = invalid(&text);
        assert!(msg.contains(want), "{text}\n→ {msg}\n(wanted `{want}`)");
    }
    // An invalid scenario yields errors, never samples or a panic.
    let s = Scenario::default();
    assert!(s.samples().is_err() && s.truth(10).is_err() && s.sensor_truths().is_err());
}

#[test]
fn per_session_revolutions_and_accumulated_readings() {
    let s: Scenario = toml::from_str(
        r#"
        rate_hz = 100.0
        speed_rpm = 60.0
        wrap = false
        mark_sessions = true
        [[sensor]]
        name = "a"
        mount = "a"
        [procedure]
        ramp_s = 0.0
        pause_s = 0.0
        turn_s = 0.5
        revolutions = 1.0
        sessions = [{ relative_deg = 0.0, revolutions = 2.0 }, { relative_deg = 90.0 }]
        "#,
    )
    .unwrap();
    let samples: Vec<_> = s.samples().unwrap().collect();
    let count = |k| samples.iter().filter(|x| x.session == Some(k)).count();
    assert_eq!((count(0), count(1)), (200, 100));
    // Accumulated: 3 revolutions of the shaft plus A's quarter turn.
    let last = samples.last().unwrap().values[0];
    assert!((last - 3.25 * TAU).abs() < 1e-12, "{last}");
}

/// Run with `cargo test --release -p calib-core --test it simulate:: -- --ignored --nocapture`.
#[test]
#[ignore = "throughput measurement, release build"]
fn generation_throughput() {
    let mut s = scenario("csrr72");
    s.procedure.revolutions = 1400.0; // ≈ 10⁷ samples × 3 channels
    let samples = s.samples().unwrap();
    let n = samples.len();
    let start = std::time::Instant::now();
    let checksum: f64 = samples.map(|x| x.values[0]).sum();
    let secs = start.elapsed().as_secs_f64();
    println!(
        "{n} samples × 3 channels in {secs:.2} s ({:.1} M samples/s), checksum {checksum}",
        n as f64 / secs / 1e6
    );
}

#[test]
fn spin_down_follows_the_friction_law_and_replaces_the_procedure() {
    let s = scenario("spindown-bearing");
    let sd = s.spin_down.clone().unwrap();
    let rate = s.rate_hz;
    let theta: Vec<f64> = s
        .samples()
        .unwrap()
        .with_truth()
        .map(|st| st.true_angles[0])
        .collect();
    assert_eq!(theta.len(), (sd.duration_s * rate) as usize + 1);
    let f = sd.friction;
    let decel = |w: f64| f.coulomb + f.viscous * w + f.quadratic * w * w;
    // Mean deceleration at the start and after 20 s, from the mean speeds of two consecutive
    // revolutions: the drag (orders 2 and 4) averages out over whole revolutions, up to the
    // change of speed within one (~1 %), and the speed's curvature adds ~1e-4 rad/s²; the
    // friction law gives 1.39 rad/s² and ~0.8 rad/s² there.
    for start in [0usize, 40_000] {
        let w = (theta[start + 1] - theta[start]) * rate;
        let span = (TAU / w * rate).round() as usize;
        let mean_speed = |i: usize| (theta[i + span] - theta[i]) * rate / span as f64;
        let (w0, w1) = (mean_speed(start), mean_speed(start + span));
        let measured = (w0 - w1) / (span as f64 / rate);
        let expected = decel(0.5 * (w0 + w1));
        assert!(
            (measured - expected).abs() < 0.01,
            "{start}: {measured} vs {expected}"
        );
    }
    // Truth is unchanged by the motion: readings − true angle = the sensor's error at the true
    // angle (to noise 0.05″ ×5σ plus half the 0.09″ resolution).
    let truth = &s.sensor_truths().unwrap()[0];
    for st in s.samples().unwrap().with_truth().step_by(997) {
        let e = wrap_pi(st.sample.values[0] - st.true_angles[0]);
        let d = arcsec(e - truth.error_at_true(st.true_angles[0]));
        assert!(d.abs() < 0.3, "{d}″");
    }

    let mut both = s.clone();
    both.procedure.relative_deg = vec![0.0, 10.0];
    assert!(matches!(
        both.validate(),
        Err(ScenarioError::SpinDownConflict { table: "procedure" })
    ));
    let mut driven = s.clone();
    driven.speed.variation_percent = 1.0;
    assert!(matches!(
        driven.validate(),
        Err(ScenarioError::SpinDownConflict { table: "speed" })
    ));
    let bad: Result<Scenario, _> = toml::from_str(
        "[spin_down]\nspeed_rpm = 60.0\nduration_s = 1.0\nfriction = { viscous = 0.1, dry = 1.0 }\n[[sensor]]\nname = \"a\"\n",
    );
    assert!(bad.unwrap_err().to_string().contains("dry"));
    let mut negative = s;
    negative.spin_down.as_mut().unwrap().friction.viscous = -0.1;
    assert!(
        negative
            .validate()
            .unwrap_err()
            .to_string()
            .contains("spin_down.friction.viscous")
    );
}

/// A `[sweep]` run: the noise-free readings stay inside each channel's range truth, reach both of
/// its ends (the strokes end at rest there), and equal the true angle plus the truth at the
/// reading; `[sweep]` with `[procedure]` and an empty stroke are refused.
#[test]
fn a_sweep_stays_in_its_range_truth() {
    let s = noiseless(scenario("joint"));
    let ranges = s.range_truth(3600).unwrap().expect("a sweep");
    let truths = s.sensor_truths().unwrap();
    let (mut lo, mut hi) = (vec![f64::INFINITY; 2], vec![f64::NEG_INFINITY; 2]);
    for st in s.samples().unwrap().with_truth() {
        for k in 0..2 {
            let r = st.sample.values[k];
            lo[k] = lo[k].min(r);
            hi[k] = hi[k].max(r);
            let e = truths[k].error_at_reading(r);
            assert!(arcsec(wrap_pi(r - e - st.true_angles[k])).abs() < 1e-6);
        }
    }
    for k in 0..2 {
        let map = ranges[k].1.as_ref().expect("less than a turn");
        // The grid's ends are the readings at the strokes' ends (1e-9 rad: rounding).
        assert!(
            (map.start() - lo[k]).abs() < 1e-9,
            "{k}: {} vs {}",
            map.start(),
            lo[k]
        );
        assert!(
            (map.end() - hi[k]).abs() < 1e-9,
            "{k}: {} vs {}",
            map.end(),
            hi[k]
        );
        assert!(map.step() <= TAU / 3600.0 + 1e-15);
    }
    let mut bad = s.clone();
    bad.procedure.relative_deg = vec![0.0, 10.0];
    assert!(matches!(
        bad.validate(),
        Err(ScenarioError::SweepConflict { table: "procedure" })
    ));
    let mut bad = s.clone();
    if let Some(sw) = bad.sweep.as_mut() {
        sw.to_deg = sw.from_deg;
    }
    assert!(matches!(
        bad.validate(),
        Err(ScenarioError::InvalidValue { .. })
    ));
}
