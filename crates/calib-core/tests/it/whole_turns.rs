//! The methods that need whole turns say first that a joint never turned one, whatever else
//! failed: the travel is the method's own check, in its error.

use calib_core::csrr::{Csrr, CsrrError, CsrrOptions};
use calib_core::multihead::{Head, Multihead, MultiheadError, MultiheadOptions};
use calib_core::tdr::{Tdr, TdrError, TdrOptions};

/// A joint swept 15°…135° and back four times at 500 Hz: 120° of travel, never a whole turn.
fn sweep() -> impl Iterator<Item = (f64, f64)> {
    (0..4 * 2 * 1200).map(|k| {
        let phase = (k % 2400) as f64;
        let deg = if phase < 1200.0 {
            15.0 + phase / 10.0
        } else {
            135.0 - (phase - 1200.0) / 10.0
        };
        (k as f64 * 0.002, deg.to_radians())
    })
}

#[test]
fn csrr_names_the_sensor_that_never_turned() {
    let mut csrr = Csrr::new(CsrrOptions::default());
    for (t, x) in sweep() {
        // B turns whole revolutions; A, the joint, does not.
        csrr.push(t, x, (t * 2.0) % std::f64::consts::TAU, None);
    }
    match csrr.finish() {
        Err(CsrrError::NoWholeTurn {
            sensor,
            turn,
            cause,
        }) => {
            assert_eq!(sensor, 'A');
            assert!((turn.span_deg - 120.0).abs() < 1e-6, "{}", turn.span_deg);
            // The solve's own error is kept as the cause.
            assert!(!matches!(*cause, CsrrError::NoWholeTurn { .. }));
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn tdr_and_multihead_say_the_same() {
    let mut tdr = Tdr::new(TdrOptions::default());
    for (t, x) in sweep() {
        tdr.push(t, x);
    }
    let err = tdr.finish().unwrap_err();
    assert!(
        matches!(&err, TdrError::NoWholeTurn { turn, .. } if (turn.span_deg - 120.0).abs() < 1e-6),
        "{err:?}"
    );
    assert!(
        err.to_string().starts_with(
            "the encoder never turned a whole revolution (its readings span 120.000°)"
        ),
        "{err}"
    );

    let heads = vec![
        Head {
            name: "h1".into(),
            nominal: 0.0,
        },
        Head {
            name: "h2".into(),
            nominal: std::f64::consts::PI,
        },
    ];
    let mut mh = Multihead::new(heads, MultiheadOptions::default()).unwrap();
    for (_, x) in sweep() {
        mh.push(&[x, x + std::f64::consts::PI]);
    }
    let err = mh.finish().unwrap_err();
    assert!(matches!(err, MultiheadError::NoWholeTurn { .. }), "{err:?}");
    assert!(err.to_string().contains("reference method"), "{err}");
}
