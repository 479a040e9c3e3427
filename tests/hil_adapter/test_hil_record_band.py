"""The HIL record's prediction band (``--record-band``): the discrepancy of the parameter file, read through
``fmu_models`` alone, evaluated at each row's horizon in windows laid over the run as ``validate`` lays them."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from fmu_models.common.params import Discrepancy, SignalDiscrepancy
from hil_adapter.core import Plant, Recorder
from hil_adapter.record_band import BAND, RecordBand, read_band_discrepancy
from hil_adapter.session import HilSetupError, serve

LEVELS = [0.05, 0.5, 0.95]


def _disc() -> Discrepancy:
    """Window 1 s, two horizon bins; roll unscaled, the x rate scaled by its departure (floor 0.5), the y rate by
    its slope (floor 1), yaw wrapped."""
    edges = [0.0, 0.5, 1.0]
    return Discrepancy(levels=LEVELS, window_s=1.0, rate_hz=50.0, signals={
        "roll_rad": SignalDiscrepancy(horizon_edges_s=edges, quantiles=[[-0.1, 0.0, 0.2], [-0.3, 0.0, 0.4]],
                                      samples=[100, 100]),
        "rate_body_x_rad_s": SignalDiscrepancy(horizon_edges_s=edges, quantiles=[[-1.0, 0.0, 1.0], [-2.0, 0.0, 2.0]],
                                               samples=[100, 100], scale_floor=0.5),
        "yaw_rad": SignalDiscrepancy(horizon_edges_s=edges, quantiles=[[-1.0, 0.0, 1.0], [-1.0, 0.0, 1.0]],
                                     samples=[100, 100], scale_floor=0.1, wrap=True),
        "rate_body_y_rad_s": SignalDiscrepancy(horizon_edges_s=edges, quantiles=[[-1.0, 0.0, 1.0], [-1.0, 0.0, 1.0]],
                                               samples=[100, 100], scale_floor=1.0, scale_by="slope"),
        "thrust_total_N": SignalDiscrepancy(horizon_edges_s=edges, quantiles=[[-1, 0, 1], [-1, 0, 1]],
                                            samples=[100, 100])})


def test_band_is_the_learned_quantile_at_each_rows_horizon_and_restarts_every_window() -> None:
    band = RecordBand(_disc(), ["roll_rad", "rate_body_x_rad_s", "yaw_rad", "altitude_m"])
    assert band.names == ["roll_rad", "rate_body_x_rad_s", "yaw_rad"]  # thrust is not recorded, altitude not learned
    assert band.columns[:4] == ["roll_rad_band_lo", "roll_rad_band_hi", "gyro_body_x_rad_s_band_lo",
                                "gyro_body_x_rad_s_band_hi"]
    t0 = 0.004
    rows = {}
    for t, roll, rate, yaw in ((t0, 0.1, 1.0, 3.1), (t0 + 0.2, 0.1, 1.5, -3.1), (t0 + 0.7, 0.2, 3.0, 3.1),
                               (t0 + 1.1, 0.3, 3.0, 3.1)):
        rows[round(t - t0, 3)] = band.values(t, {"roll_rad": roll, "rate_body_x_rad_s": rate, "yaw_rad": yaw})
    # horizon 0.2 s: first bin; the rate moved 0.5 from its window's first row: scale 0.5 + 0.5
    lo, hi, rlo, rhi, ylo, yhi = rows[0.2]
    assert (lo, hi) == pytest.approx((0.1 - 0.1, 0.1 + 0.2))
    assert (rlo, rhi) == pytest.approx((1.5 - 1.0, 1.5 + 1.0))
    # yaw went 3.1 -> -3.1: 0.083 rad the short way round, not 6.2
    dep = 2 * math.pi - 6.2
    assert (ylo, yhi) == pytest.approx((-3.1 - (dep + 0.1), -3.1 + (dep + 0.1)))
    # horizon 0.7 s: second bin, departure 2.0: scale 2.5
    lo, hi, rlo, rhi, *_ = rows[0.7]
    assert (lo, hi) == pytest.approx((0.2 - 0.3, 0.2 + 0.4)) and (rlo, rhi) == pytest.approx((3.0 - 5.0, 3.0 + 5.0))
    # 1.1 s: a new window at 1.0 s starts here, horizon 0.1 s, the departure measured from this row (0)
    lo, hi, rlo, rhi, *_ = rows[1.1]
    assert (lo, hi) == pytest.approx((0.3 - 0.1, 0.3 + 0.2)) and (rlo, rhi) == pytest.approx((3.0 - 0.5, 3.0 + 0.5))
    assert BAND == (0.05, 0.95)


def test_a_slope_scaled_band_follows_how_fast_the_output_changed_since_the_previous_row() -> None:
    band = RecordBand(_disc(), ["rate_body_y_rad_s"])
    assert band.values(0.0, {"rate_body_y_rad_s": 0.0}) == pytest.approx([-1.0, 1.0])  # no previous row: floor
    lo, hi = band.values(0.2, {"rate_body_y_rad_s": 0.4})  # 2 rad/s^2 since the previous row: scale 3
    assert (lo, hi) == pytest.approx((0.4 - 3.0, 0.4 + 3.0))


def test_a_discrepancy_of_no_recorded_output_or_none_at_all_is_refused(quadrotor_fmu: Path, tmp_path: Path) -> None:
    only_thrust = _disc().model_copy(update={"signals": {"thrust_total_N": _disc().signals["thrust_total_N"]}})
    with pytest.raises(ValueError, match="none of the recorded outputs"):
        RecordBand(only_thrust, ["roll_rad"])
    bare = tmp_path / "bare.json"
    bare.write_text(json.dumps({"mass_kg": 1.2}))
    with pytest.raises(ValueError, match=r"bare\.json has no 'discrepancy' block"):
        read_band_discrepancy(quadrotor_fmu, bare)
    with pytest.raises(ValueError, match="no parameter file embedded"):
        read_band_discrepancy(quadrotor_fmu)
    with pytest.raises(HilSetupError, match="give --record"):
        serve(quadrotor_fmu, "ardupilot-json", record_band=True, duration_s=0.1)
    with pytest.raises(HilSetupError, match="no 'discrepancy' block"):
        serve(quadrotor_fmu, "ardupilot-json", record=tmp_path / "r.csv", band_params=bare, duration_s=0.1)


def test_the_record_holds_the_band_around_each_output_and_reads_back(quadrotor_fmu: Path, tmp_path: Path) -> None:
    from identification.logs.readers import read_log

    params = tmp_path / "params.json"
    params.write_text(json.dumps({"discrepancy": json.loads(_disc().model_dump_json())}))
    plant = Plant(quadrotor_fmu)
    band = RecordBand(read_band_discrepancy(quadrotor_fmu, params), plant.outputs)
    rec = Recorder(tmp_path / "band.csv", [1, 2, 3, 4], list(plant.inputs), plant.outputs, band)
    try:
        for _ in range(100):
            plant.apply(dict.fromkeys(range(1, 5), 1600.0))
            plant.advance(0.02)
            rec.write(plant.t_s, dict.fromkeys(range(1, 5), 1600.0), plant.inputs, plant.state)
    finally:
        rec.close()
        plant.close()
    log = read_log(rec.path)
    for col in ("roll_rad", "gyro_body_x_rad_s"):
        y, lo, hi = (log.signal(c).values for c in (col, f"{col}_band_lo", f"{col}_band_hi"))
        assert len(lo) == 100 and np.all(lo < y) and np.all(y < hi)
    h = np.round(log.signal("roll_rad").t_s - log.signal("roll_rad").t_s[0], 6) % 1.0
    width = log.signal("roll_rad_band_hi").values - log.signal("roll_rad_band_lo").values
    np.testing.assert_allclose(width, np.where(h < 0.5, 0.3, 0.7))


def test_serve_writes_the_band_columns_of_the_embedded_or_given_discrepancy(quadrotor_fmu: Path,
                                                                            tmp_path: Path) -> None:
    params = tmp_path / "params.json"
    params.write_text(json.dumps({"discrepancy": json.loads(_disc().model_dump_json())}))
    cfg = tmp_path / "bench.toml"
    cfg.write_text(f'[record]\npath = "{(tmp_path / "r.csv").as_posix()}"\nband_params = "{params.as_posix()}"\n')
    result = serve(quadrotor_fmu, "ardupilot-json", cfg, port=0, duration_s=0.3)
    with (tmp_path / "r.csv").open() as fh:
        header = next(csv.reader(fh))
    cols = ("gyro_body_x_rad_s", "gyro_body_y_rad_s", "roll_rad", "yaw_rad")
    assert header[-8:] == [f"{c}_band_{s}" for c in cols for s in ("lo", "hi")]
    assert result.band_outputs == ("rate_body_x_rad_s", "rate_body_y_rad_s", "roll_rad", "yaw_rad")
    assert any("prediction band of rate_body_x_rad_s, rate_body_y_rad_s, roll_rad, yaw_rad" in line
               for line in result.lines())
