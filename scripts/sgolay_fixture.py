#!/usr/bin/env python3
"""Reference values for src/ngsim/smooth.rs, computed independently with scipy.

Writes tests/fixtures/sgolay.json: a deterministic noisy signal (a fixed linear congruential
generator, so no numpy random stream is involved) and scipy.signal.savgol_filter(..., mode="interp")
outputs for several window lengths and polynomial orders.

    pip install --target /tmp/sg scipy numpy && PYTHONPATH=/tmp/sg python3 scripts/sgolay_fixture.py
"""
import json
import math
import pathlib

import scipy
from scipy.signal import savgol_filter

state = 12345


def uniform():
    global state
    state = (1103515245 * state + 12345) % 2**31
    return state / 2**31


n = 120
signal = [10.0 * math.sin(0.07 * i) + 0.5 * i + (uniform() - 0.5) for i in range(n)]
cases = []
for window, order in [(11, 3), (21, 2), (5, 4), (15, 0)]:
    out = savgol_filter(signal, window, order, mode="interp")
    cases.append({"window": window, "order": order, "output": [float(v) for v in out]})
path = pathlib.Path(__file__).resolve().parent.parent / "tests" / "fixtures" / "sgolay.json"
path.write_text(json.dumps({"scipy": scipy.__version__, "input": signal, "cases": cases}, indent=1) + "\n")
print(f"wrote {path} (scipy {scipy.__version__})")
