"""Numbers as people read them: sample times on the decimal grid of the period, and every float a
file shows written as its shortest round-trip text (no 0.0040000000000000001, no 1.6400000000000001)."""

from __future__ import annotations

import csv
import json
import re
from decimal import Decimal
from pathlib import Path

import numpy as np
import pytest

from singplan.outputs.exports import to_csv_deg, to_ros2_json, to_ros2_yaml
from singplan.results.build import sample_time, sample_times
from singplan.results.trajectory import load


@pytest.mark.parametrize("period", [0.004, 0.001, 0.0001, 0.008, 0.012, 0.0035, 0.1, 1.0, 0.00123456789])
def test_sample_k_is_the_float_nearest_k_times_the_period_as_written(period: float) -> None:
    count = 200_001
    t = sample_times(count, period)
    k = np.arange(0, count, 997)
    assert t[k].tolist() == [float(Decimal(int(i)) * Decimal(repr(period))) for i in k]
    assert [sample_time(int(i), period) for i in k[:50]] == t[k[:50]].tolist()
    # at most one float step from the plain product, so timing and checks see the same clock
    assert np.all(np.abs(t - np.arange(count) * period) <= np.spacing(t))
    assert np.all(np.diff(t) > 0)


def test_a_period_with_no_short_decimal_falls_back_to_the_product() -> None:
    period = 1 / 300  # 0.0033333333333333335: m * k would pass 2**53
    assert sample_times(10**6, period).tolist() == (np.arange(10**6) * period).tolist()


def test_the_demo_files_show_times_on_the_grid_and_shortest_numbers(planned_kuka: Path) -> None:
    with open(planned_kuka / "trajectory.csv", newline="") as stream:
        rows = list(csv.reader(stream))
    assert rows[1][0] == "0.0" and rows[2][0] == "0.004" and rows[411][0] == "1.64" and rows[-1][0] == "1.904"
    for row in rows[1:]:
        assert all(repr(float(cell)) == cell for cell in row)  # shortest round-trip text, read back exactly
    doc = json.loads((planned_kuka / "trajectory.json").read_text())
    assert doc["t"][410] == 1.64 and doc["metrics"]["duration_s"] == 1.904
    times = [doc["metrics"]["max_stopping_distance_at_s"]] + [e["t"] for e in doc["events"]] + [
        v for s in doc["segments"] for v in (s["t0"], s["t1"])] + [v for m in doc["moves"] for v in (m["t0"], m["t1"])]
    for t in times:  # each on the 4 ms grid as written: at most 3 decimals
        assert Decimal(repr(t)) == Decimal(repr(t)).quantize(Decimal("0.001")), t
    text = (planned_kuka / "trajectory.json").read_text()
    assert not re.search(r"\d\.\d*0000000000000\d", text)  # no 1.6400000000000001


def test_the_exports_write_shortest_numbers(planned_kuka: Path) -> None:
    traj = load(planned_kuka)
    text = to_csv_deg(traj)
    first, second = text.splitlines()[1:3]
    assert first.split(",")[0] == "0.0" and second.split(",")[0] == "0.004"
    assert all(repr(float(cell)) == cell for line in text.splitlines()[1:] for cell in line.split(","))
    for exported in (to_ros2_yaml(traj), to_ros2_json(traj)):
        numbers = re.findall(r"-?\d+\.\d+(?:e-?\d+)?", exported)
        assert all(repr(float(n)) == n or repr(float(n)) == n.replace(".0e", "e") for n in numbers)
