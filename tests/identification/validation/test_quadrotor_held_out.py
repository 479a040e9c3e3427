"""The shared PX4 SITL flight: the FMU with the parameters ``identify quadrotor`` found, replayed by ``validate``
on the held-out segments the identification did not fit (0.5 s restarts from the logged state)."""

from __future__ import annotations

from pathlib import Path

from fmu_models.fmi.host import FmuHost
from fmu_models.quadrotor.params import QuadrotorParams
from identification.logs.readers import read_log
from identification.quadrotor import identify as q
from identification.validation import output_map
from identification.validation.replay import replay
from tests.conftest import shared_data


def test_identified_fmu_beats_persistence_on_held_out_segments(quadrotor_fmu: Path) -> None:
    """Body rates beat persistence with the whole 90 % skill interval above +0.5, total thrust beats it, no
    signal fails (angles included: each restart carries the motors' lagged thrust). The identified values go in
    as FMU parameters, as ``build --params`` would bake them in."""
    path = shared_data("quadrotor_px4_sitl", "px4_sitl_fmu_sysid.ulg")
    log = read_log(path)
    res = q.identify_quadrotor(log, QuadrotorParams())
    values = {n: float(getattr(res.params, n)) for n in res.free}
    assert values["tau_motor_s"] > 0.005  # the case the lagged restart matters for
    spans = [(s.t0_s, s.t1_s) for s in res.held_out_segments]
    with FmuHost(quadrotor_fmu) as host:
        val = replay(host, log, path, output_map.QUADROTOR, rate_hz=50.0, window_s=0.5, start_values=values,
                     segments_s=spans)
    for name in ("rate_body_x_rad_s", "rate_body_y_rad_s", "rate_body_z_rad_s"):
        assert val.scores[name].interval.lo > 0.5, (name, val.scores[name].reason)
    assert val.scores["thrust_total_N"].verdict == "pass", val.scores["thrust_total_N"].reason
    assert not val.failed, {n: val.scores[n].reason for n in val.failed}
    assert sum(val.included) >= 40  # the held-out segments, not a handful of windows
