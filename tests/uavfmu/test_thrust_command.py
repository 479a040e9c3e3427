"""``uavfmu identify thrust`` command: LOG=MASS parsing, exit statuses, printed table, metrics JSON."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.identification.thrust.test_thrust_workflow import VoltLog, fake_logs  # noqa: F401 - fixture
from uavfmu.cli import main
from uavfmu.commands.identify_thrust import parse_flights


def test_parse_flights_masses() -> None:
    got = parse_flights(["a.bin=1.3", "b.bin"], 1.1)
    assert got == [(Path("a.bin"), 1.3), (Path("b.bin"), 1.1)]
    with pytest.raises(ValueError, match=r"flight b\.bin: no mass"):
        parse_flights(["b.bin"], None)
    with pytest.raises(ValueError, match=r"flight a\.bin: mass = 'x'"):
        parse_flights(["a.bin=x"], None)


def test_cli_prints_per_flight_summaries_and_table(fake_logs: dict, tmp_path: Path, capsys) -> None:  # noqa: F811
    fake_logs["a"] = VoltLog(1.3, 12.4, 10.8, seed=1)
    fake_logs["b"] = VoltLog(1.0, 11.6, 10.2, seed=2)
    out = tmp_path / "p.json"
    argv = ["identify", "thrust", "a=1.3", "b", "--mass", "1.0", "--out", str(out)]
    assert main(argv) == 2  # two masses and no --fmu-mass-kg: refused, naming the option
    assert "--fmu-mass-kg" in capsys.readouterr().err and not out.exists()
    rc = main([*argv, "--fmu-mass-kg", "1.1"])
    text = capsys.readouterr().out
    assert rc == 0
    assert "a: 1.3 kg" in text and "b: 1.0 kg" in text and "pooled RMSE" in text and "constant m g" in text
    assert "WIN" in text and "verdict: model beats every baseline" in text
    m = json.loads(out.with_suffix(".metrics.json").read_text())
    assert [f["flight"] for f in m["flights"]] == ["a", "b"] and m["verdict"] == "win"
    assert json.loads(out.read_text())["quadrotor"]["mass_kg"] == 1.1


def test_cli_exit_3_when_a_baseline_wins_and_each_override_says_what_it_did(
    fake_logs: dict, tmp_path: Path, capsys  # noqa: F811
) -> None:
    fake_logs["hi"] = VoltLog(1.2, 12.6, 12.4, seed=5, voltage=False)
    fake_logs["lo"] = VoltLog(1.2, 10.4, 10.2, seed=6, voltage=False)
    out = tmp_path / "p.json"
    argv = ["identify", "thrust", "hi", "lo", "--mass", "1.2", "--calibrate", "off", "--no-battery-state",
            "--mfs", "1", "--out", str(out)]
    assert main(argv) == 3
    err = capsys.readouterr().err
    assert "MODEL LOSES" in err and "--write-losing-model writes it" in err and not out.exists()
    assert main([*argv, "--write-losing-model"]) == 3  # the exit status still tells the truth
    err = capsys.readouterr().err
    assert "MODEL LOSES" in err and "override: --write-losing-model: wrote" in err and out.exists()
    with pytest.raises(SystemExit):  # the catch-all override is gone
        main([*argv, "--force"])


def test_cli_bad_mass_is_exit_2_naming_the_flight(tmp_path: Path, capsys) -> None:
    assert main(["identify", "thrust", "x.bin=-2", "--out", str(tmp_path / "p.json")]) == 2
    assert "flight x.bin: field mass_kg = -2.0" in capsys.readouterr().err


def test_report_groups_the_comparisons_by_side_information_with_a_like_for_like_headline(
    fake_logs: dict  # noqa: F811
) -> None:
    from identification.thrust.workflow import FlightSpec, ThrustConfig, identify_thrust
    from uavfmu.commands.identify_thrust import format_report

    fake_logs["hi"] = VoltLog(1.2, 12.6, 12.4, seed=5, voltage=False)
    fake_logs["lo"] = VoltLog(1.2, 10.4, 10.2, seed=6, voltage=False)
    r = identify_thrust(ThrustConfig(flights=(FlightSpec(Path("hi"), 1.2), FlightSpec(Path("lo"), 1.2)),
                                     calibrate="on", n_mfs=1))
    text = format_report(r)
    raw, state, cal = (text.index(f"  [{lv}]") for lv in ("raw", "battery state", "calibrated"))
    assert raw < state < cal
    assert "(reported, not in the verdict)" in text[raw:state] and "not in the verdict" not in text[state:]
    assert "model vs poly sum u^2, sum u (battery state)" in text[state:cal]
    assert "model (calibrated) vs constant m g (calibrated)" in text[cal:] or \
        "model without battery state (calibrated) vs constant m g (calibrated)" in text[cal:]
    h = r.metrics["headline"]
    assert f"headline (like for like, battery state): model {r.pooled['model']:.3f} N vs {h['baseline']}" in text
    assert h["baseline"].endswith("(battery state)")
