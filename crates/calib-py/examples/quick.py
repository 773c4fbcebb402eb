"""A worked example: calibrate the bundled example run with calib from Python.

    python crates/calib-py/examples/quick.py [LOG]

Prints the figures `calib csrr LOG` prints (sessions, orders, fit residual, uncertainty, and per
channel the peak-to-peak, RMS and largest harmonics), writes the correction tables a.csv and
b.csv into calib-py-out/, and plots both error maps with matplotlib where it is installed.
"""

import pathlib
import sys

import calib

HERE = pathlib.Path(__file__).resolve().parent
LOG = pathlib.Path(sys.argv[1]) if len(sys.argv) > 1 else HERE.parents[2] / "testdata/examples/quick.mcap"

res = calib.csrr_log(LOG, a="a", b="b")
details = res.report["details"]
sessions = res.report["sessions"]
revs = [s["revolutions"] for s in sessions]
deltas = ", ".join(f"{s['relative_rotation_deg']:.1f}°" for s in sessions)

print("CSRR self-calibration of `a` and `b` — joint least squares\n")
print(f"  sessions       {len(sessions)} of {min(revs):.2f}–{max(revs):.2f} revolutions at Δ = {deltas}")
print(
    f"  orders         1–{details['max_order']} tested, {len(details['orders_kept'])} kept above "
    f"the noise, {len(details['excluded_orders'])} left out"
)
print(f"  fit residual   {details['residual_rms_arcsec']:.4f}″ RMS per sample, {details['iterations']} iterations")
u = details["uncertainty"]
print(
    "  uncertainty u  "
    + ", ".join(f"max {u[n]['u_max_arcsec']:.4f}″ rms {u[n]['u_rms_arcsec']:.4f}″ ({n})" for n in ("a", "b"))
    + " — standard, at every table point\n"
)
print(f"  {'channel':<8} {'p-p before':>10} {'rms':>8}  largest orders")
for name, ch in res.channels.items():
    top = ", ".join(f"{h['order']}: {h['amplitude_arcsec']:.3f}″" for h in ch.harmonics[:3])
    print(f"  {name:<8} {ch.peak_to_peak_arcsec:>9.3f}″ {ch.rms_arcsec:>7.3f}″  {top}")
for w in res.warnings:
    print(f"warning: {w}")

out = pathlib.Path("calib-py-out")
out.mkdir(exist_ok=True)
for name, ch in res.channels.items():
    ch.table.write(out / f"{name}.csv")
print(f"\nwrote a.csv and b.csv into {out}")

try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    print("(matplotlib is not installed: no plot)")
else:
    fig, ax = plt.subplots(figsize=(8, 4))
    for name, ch in res.channels.items():
        ax.plot(ch.angle_deg, ch.error_arcsec, label=f"{name} ({ch.peak_to_peak_arcsec:.1f}″ p-p)")
    ax.set_xlabel("reading (°)")
    ax.set_ylabel("error (″)")
    ax.set_title(f"CSRR error maps of {LOG.name}")
    ax.legend()
    fig.savefig(out / "maps.png", dpi=100, bbox_inches="tight")
    print(f"plotted the maps to {out / 'maps.png'}")
