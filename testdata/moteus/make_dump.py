#!/usr/bin/env python3
"""Writes dump.txt: a moteus calibration dump (`moteus_tool --calibrate --cal-write-raw FILE`
layout: `CAL start`, `direction phase encoder` lines, `CAL done`) simulated with a known truth,
as `cli/tests/it/reference_setups_cli.rs::moteus_dump_is_calibrated_within_its_tolerance` writes
it: 21 pole pairs, the rotor pulled by a ripple of 6 per electrical turn (0.15°), an encoder
erring by 0.2° at order 1 and 0.15° at order 2, read as raw uint16 (19.8″ quantum), 1060
samples a turn each way after 4 that moteus drops. The truth: e(θ) = 0.2°·cos(θ + 0.5) +
0.15°·cos(2θ − 1), error = reading − true angle."""
import math

P = 21.0
N = 1060
TAU = 2 * math.pi


def e(th):
    return math.radians(0.2) * math.cos(th + 0.5) + math.radians(0.15) * math.cos(2 * th - 1.0)


def rho(phi):
    return math.radians(0.15) * math.cos(6 * phi + 0.3)


def line(direction, k):
    phase = k * P * 65536.0 / N
    c = phase / 65536.0 * TAU / P + 1.0
    theta = c + rho(P * (c - 1.0))
    enc = int(round((theta + e(theta)) / TAU * 65536.0)) % 65536
    return f"{direction} {int(round(phase)) % 65536} {enc}\n"


with open("dump.txt", "w") as f:
    f.write("CAL start\n")
    for k in range(N + 4):
        f.write(line(1, k))
    for k in reversed(range(N + 4)):
        f.write(line(2, k))
    f.write("CAL done\n")
