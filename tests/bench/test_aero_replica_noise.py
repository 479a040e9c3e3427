"""The fixed-wing replica reads each segment's start from samples as noisy as a real log's: the last sample at or
before the start carries the replica's noise (white and AR(1) alike), not the original log's (nearly noise-free
SITL) value, and the AR(1) part is stationary from there on instead of starting at 0."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))  # the bench imports its sibling scripts
import aero_coverage
import aero_replica as bench

from fmu_models.fixed_wing.model import FixedWingModel
from fmu_models.fixed_wing.params import FixedWingParams
from fmu_models.signals.pwm_mapping import PwmMapping
from identification.aero import model as aero
from identification.flights import synthetic
from identification.logs.log_state import start_signal_values
from identification.logs.readers import read_log


def test_stationary_ar1_has_its_long_run_std_from_the_first_sample() -> None:
    rng = np.random.default_rng(0)
    white, coloured, pole = 0.5, 1.0, aero_coverage.POLE
    x = np.array([aero_coverage.white_plus_ar1(rng, (4, 2), white, np.array([coloured, 2 * coloured]),
                                               stationary=True) for _ in range(20000)])
    np.testing.assert_allclose(x.std(axis=0)[0], np.hypot(white, [coloured, 2 * coloured]), rtol=0.03)
    np.testing.assert_allclose(x.std(axis=0)[3], np.hypot(white, [coloured, 2 * coloured]), rtol=0.03)
    lag1 = np.mean(x[:, 0, 0] * x[:, 1, 0]) / (white**2 + coloured**2)
    assert abs(lag1 - pole * coloured**2 / (white**2 + coloured**2)) < 0.03
    # started at 0 (the coverage study's manoeuvres), its first sample has only the drive's share
    y = np.array([aero_coverage.white_plus_ar1(rng, (4,), white, coloured) for _ in range(20000)])
    assert abs(y.std(axis=0)[0] - np.hypot(white, coloured * np.sqrt(1 - pole**2))) < 0.03


def test_a_segment_start_is_read_with_the_noise_of_one_sample(tmp_path: Path) -> None:
    """Segments starting on a log sample: the state read there is that sample's, so its error is the noise of one
    sample, std sqrt(white^2 + coloured^2) = sqrt(2) x 0.003 rad in roll (0 when that sample kept the noise-free
    original value)."""
    t, sig = synthetic.fixed_wing_flight(seconds=30.0, rate_hz=50.0)  # noise-free
    log = read_log(synthetic.write_csv_log(tmp_path / "wing.csv", t, sig))
    mapping = PwmMapping.load(synthetic.write_mapping_toml(tmp_path / "mapping.toml"))
    model = FixedWingModel(FixedWingParams())
    p = np.array(model.params.starts(), dtype=float)
    segments = [aero.Segment(round(1.0 + 2.2 * k, 2), round(2.8 + 2.2 * k, 2)) for k in range(12)]
    starts = np.array([s.t0_s for s in segments])
    assert np.all(np.isin(np.round(starts * 50.0), np.round(t * 50.0)))  # every start on a sample
    truth = start_signal_values(log, starts, True)
    errors = []
    for seed in range(8):
        rep = bench.replica_log(log, model, p, segments, mapping, ["roll_rad", "rate_body_x_rad_s"], 50.0,
                                np.random.default_rng(seed))
        errors.append(start_signal_values(rep, starts, True)["roll_rad"] - truth["roll_rad"])
        inside = rep.signal("roll_rad").resample(np.array([segments[0].t0_s + 0.5]))
        assert np.all(np.isfinite(inside))
    sd = float(np.sqrt(np.mean(np.square(errors))))
    assert 0.8 * np.sqrt(2) * 0.003 < sd < 1.2 * np.sqrt(2) * 0.003, sd
    # the exact-start study keeps the original value there: no start error at all
    exact = bench.replica_log(log, model, p, segments, mapping, ["roll_rad", "rate_body_x_rad_s"], 50.0,
                              np.random.default_rng(0), exact_start=True)
    np.testing.assert_allclose(start_signal_values(exact, starts, True)["roll_rad"], truth["roll_rad"], atol=1e-12)
