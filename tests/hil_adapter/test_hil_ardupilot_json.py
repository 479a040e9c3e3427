"""ArduPilot SITL JSON interface on loopback UDP: packet layouts, frame_count semantics, a closed-loop hover."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil_adapter.ardupilot_json import ArduPilotJsonServer, UdpTransport
from hil_adapter.core import Plant, Recorder
from hil_adapter.packets import SERVO16_MAGIC, SERVO32_MAGIC, PacketError, ServoPacket, parse_json_state
from identification.logs.readers import read_log
from tests.fakes.hil import FakeSitl, controller_inputs, hold_10m_autopilot, recorded, serving

RATE_HZ = 250


def test_servo_packet_layouts_round_trip() -> None:
    p16 = ServoPacket(400, 7, tuple(range(1000, 1016)))
    raw = p16.pack()
    assert len(raw) == 40 and int.from_bytes(raw[:2], "little") == SERVO16_MAGIC
    assert ServoPacket.unpack(raw) == p16
    p32 = ServoPacket(50, 2**32 - 1, tuple(range(1100, 1132)))
    assert len(p32.pack()) == 72 and int.from_bytes(p32.pack()[:2], "little") == SERVO32_MAGIC
    assert ServoPacket.unpack(p32.pack()) == p32
    with pytest.raises(PacketError, match="magic 1234"):
        ServoPacket.unpack(b"\xd2\x04" + raw[2:])
    with pytest.raises(PacketError, match="must be 40 bytes, got 39"):
        ServoPacket.unpack(raw[:-1])


@pytest.fixture
def server(quadrotor_fmu: Path, tmp_path: Path):
    plant = Plant(quadrotor_fmu)
    rec = Recorder(tmp_path / "hil.csv", [1, 2, 3, 4], list(plant.inputs), plant.outputs)
    srv = ArduPilotJsonServer(plant, UdpTransport("127.0.0.1", 0), recorder=rec)
    with serving(srv, poll_s=0.05):
        yield srv
    rec.close()
    srv.transport.close()
    plant.close()


def test_at_rest_imu_reads_gravity_and_resends_and_restarts(server) -> None:
    sitl = FakeSitl(server.transport.address)
    for k in range(1, RATE_HZ + 1):  # 1 s on the ground with the motors idle: the landing gear settles
        st0 = sitl.exchange(k, [1000] * 4)
    assert st0["imu"]["accel_body"][2] == pytest.approx(-9.80, abs=0.02)
    assert st0["imu"]["gyro"] == pytest.approx([0, 0, 0], abs=1e-6)
    assert st0["position"] == pytest.approx([0, 0, 0], abs=0.02)
    assert st0["timestamp"] == pytest.approx(1.0)
    again = sitl.exchange(RATE_HZ, [1000] * 4)  # a repeated frame_count is a resend: same answer, no step
    assert again == st0 and server.stats.resends == 1
    sitl.exchange(RATE_HZ + 1, [1000] * 4)
    sitl.exchange(RATE_HZ + 4, [1000] * 4)
    assert server.stats.dropped == 2
    sitl.sock.sendto(ServoPacket(RATE_HZ, RATE_HZ + 2, (1000,) * 16).pack(), server.transport.address)  # late
    st_now = sitl.exchange(RATE_HZ + 5, [1000] * 4)
    assert server.stats.out_of_order == 1 and st_now["timestamp"] == pytest.approx(1.0 + 3 / RATE_HZ)
    back = sitl.exchange(1, [1000] * 4)  # frame_count back to 1: SITL restarted -> FMU restarted
    # the restarted SITL gets time since its own start (SIM_JSON adds every timestamp step to its clock), the
    # vehicle is back at its start state, and the record goes on as one log whose time only grows
    assert server.stats.restarts == 1 and back["timestamp"] == pytest.approx(1 / RATE_HZ)
    assert back["position"] == pytest.approx([0, 0, 0], abs=0.02)
    assert server.plant.t_s == pytest.approx(st_now["timestamp"] + 1 / RATE_HZ)
    rec_t = read_log(recorded(server).path).signal("altitude_m").t_s
    assert len(rec_t) == server.stats.steps and np.all(np.diff(rec_t) > 0)  # one continuous record
    sitl.sock.sendto(b"\x00\x01garbage", server.transport.address)
    sitl.exchange(2, [1000] * 4)  # still answering
    assert server.stats.malformed == 1


def test_closed_loop_hover_at_10_m_through_json(server) -> None:
    sitl = FakeSitl(server.transport.address)
    ap = hold_10m_autopilot()
    dt = 1.0 / RATE_HZ
    pwm = [1000] * 4
    alts = []
    for k in range(1, round(35.0 * RATE_HZ) + 1):
        s = sitl.exchange(k, pwm)
        q = tuple(s["quaternion"])
        y = controller_inputs(q, tuple(s["imu"]["gyro"]), -s["position"][2], tuple(s["velocity"]))
        cmd = ap(k * dt, y)
        pwm = [round(cmd[f"pwm_{i}_us"]) for i in range(1, 5)]
        alts.append(-s["position"][2])
    alts = np.array(alts)
    hold = alts[round(15.0 * RATE_HZ):]  # the last 20 s
    assert np.all(np.abs(hold - 10.0) < 0.5), (hold.min(), hold.max())
    assert server.stats.steps == len(alts) and server.stats.malformed == 0
    # everything in and out was recorded, readable by the project's log readers
    log = read_log(recorded(server).path)
    assert len(log.signal("altitude_m").t_s) == len(alts)
    assert abs(log.signal("altitude_m").values[-1] - 10.0) < 0.5


@pytest.fixture(scope="module")
def fuzz_server(quadrotor_fmu: Path):
    plant = Plant(quadrotor_fmu)
    yield ArduPilotJsonServer(plant, transport=None)  # type: ignore[arg-type]  (handle() only)
    plant.close()


@settings(max_examples=300, deadline=None)
@given(data=st.binary(max_size=120))
def test_fuzzed_datagrams_never_crash(fuzz_server, data: bytes) -> None:
    srv = fuzz_server
    before = srv.stats.steps + srv.stats.malformed + srv.stats.resends
    out = srv.handle(data)
    assert out is None or json.loads(out)["timestamp"] >= 0
    assert srv.stats.steps + srv.stats.malformed + srv.stats.resends == before + 1


@settings(max_examples=200, deadline=None)
@given(rate=st.integers(1, 65535), count=st.integers(0, 2**32 - 1),
       pwm=st.lists(st.integers(0, 65535), min_size=16, max_size=16))
def test_fuzzed_servo_values_never_crash(fuzz_server, rate: int, count: int, pwm: list[int]) -> None:
    srv = fuzz_server
    out = srv.handle(ServoPacket(rate, count, tuple(pwm)).pack())
    if out is not None:
        state = json.loads(out)
        assert all(np.isfinite(state["position"]))


def test_fixed_wing_reply_has_airspeed_and_gravity(fixed_wing_fmu: Path) -> None:
    plant = Plant(fixed_wing_fmu, start_values={"init_pos_down_m": -100.0, "init_vel_body_x_m_s": 25.0})
    try:
        srv = ArduPilotJsonServer(plant, transport=None)  # type: ignore[arg-type]  (handle() only)
        pwm = (1500, 1500, 1000, 1500) + (0,) * 12  # surfaces centred, throttle off: a glide
        state = json.loads(srv.handle(ServoPacket(50, 1, pwm).pack()))
        assert state["airspeed"] == pytest.approx(25.0, abs=0.5)
        assert plant.inputs == pytest.approx({"aileron_rad": 0.0, "elevator_rad": 0.0, "throttle": 0.0,
                                              "rudder_rad": 0.0})
        assert state["position"][2] == pytest.approx(-100.0, abs=1.0)
    finally:
        plant.close()


def test_json_state_keeps_doubles_exact_and_floats_float32_exact() -> None:
    """SITL reads timestamp and position as doubles, the IMU, velocity and quaternion as floats."""
    from hil_adapter.packets import json_state

    rng = np.random.default_rng(7)
    for _ in range(200):
        v = rng.normal(size=17) * 10.0 ** rng.integers(-8, 5, size=17)
        state = parse_json_state(json_state(v[0], v[1:4], v[4:7], v[7:10], v[10:13], v[13:17], airspeed_m_s=v[0]))
        assert state["timestamp"] == v[0] and state["position"] == list(v[7:10])
        floats = [*state["imu"]["gyro"], *state["imu"]["accel_body"], *state["velocity"], *state["quaternion"],
                  state["airspeed"]]
        sent = np.concatenate([v[1:7], v[10:17], v[:1]])
        assert np.array_equal(np.float32(floats), np.float32(sent))
    with pytest.raises(PacketError, match="non-finite"):
        json_state(0.0, [0.0, np.inf, 0.0], [0, 0, 0], [0, 0, 0], [0, 0, 0], [1, 0, 0, 0])


def test_outputs_sitl_cannot_take_restart_the_simulation(quadrotor_fmu: Path) -> None:
    """A state beyond float32 in the reply is handled like an FMU error: logged, counted, restarted."""
    plant = Plant(quadrotor_fmu)
    try:
        srv = ArduPilotJsonServer(plant, transport=None)  # type: ignore[arg-type]  (handle() only)
        for k in range(1, 4):
            assert srv.handle(ServoPacket(400, k, (1000,) * 16).pack()) is not None
        advance = plant.advance

        def runaway(dt_s: float) -> dict[str, float]:
            plant.state = {**advance(dt_s), "accel_body_x_m_s2": 1e39}
            plant.imu = ((1e39, 0.0, 0.0), (0.0, 0.0, 0.0))  # the mean over the step, what the reply carries
            return plant.state

        plant.advance = runaway  # type: ignore[method-assign]
        state = json.loads(srv.handle(ServoPacket(400, 4, (1000,) * 16).pack()))
        assert plant.fmu_errors == 1 and "float32" in plant.last_error and plant.fmu_t_s == 0.0
        assert plant.reinstantiations == 1  # a fresh instance, the clock goes on: time never goes backwards
        assert state["timestamp"] == pytest.approx(4 / 400) and np.isfinite(state["imu"]["accel_body"]).all()
        restart = plant.restart

        def runaway_start() -> None:
            restart()
            plant.state = {**plant.state, "accel_body_x_m_s2": 1e39}

        plant.restart = runaway_start  # type: ignore[method-assign]
        assert srv.handle(ServoPacket(400, 5, (1000,) * 16).pack()) is None  # nothing to send, nothing raised
        assert plant.fmu_errors == 2
    finally:
        plant.close()
