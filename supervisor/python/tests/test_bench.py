"""`harvemu bench`'s Python rows: python-monitor and the recv loop's python-recv rows.

Each row runs the Python package in a process of its own; what python-monitor reports must be
that monitor's own run, frame for frame, and the recv rows must be measured side by side in one
run. Speeds themselves are the bench's to report, not a test's to assert. The harvemu binary is
found as conftest.py says.
"""

import json
import pathlib
import subprocess
import sys

import pytest

from harvemu import monitor

ROOT = pathlib.Path(__file__).parents[3]


def bench(harvemu_bin, *args):
    """`harvemu bench ARGS --json` with this Python: its rows."""
    out = subprocess.run(
        [harvemu_bin, "bench", *args, "--python", sys.executable, "--json"],
        cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    return [json.loads(line) for line in out.stdout.splitlines()]


def test_the_bench_row_is_the_monitors_own_run(harvemu_bin):
    rows = bench(harvemu_bin, "--only", "python-monitor", "--python-seconds", "20")
    assert len(rows) == 1, out.stdout
    row = rows[0]
    direct = monitor.run(20)
    assert row["scenario"] == "python-monitor"
    assert row["python"] == sys.executable
    # The same seed: the same frames at the same times, whoever runs the monitor.
    assert row["digest"] == direct["digest"]
    assert row["frames"] == direct["frames"] > 0
    assert row["virtual_seconds"] == direct["bus_seconds"] >= 20
    assert row["us_per_frame"] > 0 and row["speedup"] > 0


def test_a_python_without_the_package_is_a_clear_error(harvemu_bin):
    out = subprocess.run(
        [harvemu_bin, "bench", "--only", "python-monitor", "--python", "/nonexistent/python3"],
        cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert out.returncode == 2, out
    assert "/nonexistent/python3 -m harvemu.monitor" in out.stderr, out.stderr
    assert "pip install supervisor/python" in out.stderr, out.stderr


def test_the_recv_rows_measure_both_buses_in_one_run(harvemu_bin):
    rows = {r["scenario"]: r
            for r in bench(harvemu_bin, "--only", "python-recv", "--python-frames", "5000")}
    assert set(rows) == {"python-virtual", "python-recv", "python-recv-passive"}
    virtual = rows["python-virtual"]
    assert virtual["ratio"] is None
    for row in rows.values():
        assert row["frames"] == 5000 and row["python"] == sys.executable
        assert row["frames_per_second"] == pytest.approx(5000 / row["wall_seconds"])
    for name in ("python-recv", "python-recv-passive"):
        assert rows[name]["ratio"] == pytest.approx(
            rows[name]["frames_per_second"] / virtual["frames_per_second"])
