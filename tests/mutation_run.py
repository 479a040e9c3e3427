"""``make mutation``: mutmut on the modules whose mistakes cost users most, each group against the tests that
guard it: ``python tests/mutation_run.py [GROUP ...]`` (default: all), then ``tests/mutation_report.py``;
``--survivors GROUP ...`` runs again only what survived, after tests were added.

Each group runs in its own copy of the repository (``.mutation/<group>``, git-ignored) with its own
``[tool.mutmut]`` table, so a mutant only runs the tests of its group (mutmut then picks, per mutant, those that
reach the mutated function). The property tests run at 5 % of their examples (``UAVFMU_FUZZ_SCALE``); the
config schemas' property test is left out (its hand-written tests name every message), and so are the FMU
replay tests of validation.py (about 14 s per mutant): its verdict code is scored on its fast tests.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
WORK = REPO / ".mutation"
#: group -> (modules to mutate, test files, extra pytest arguments)
GROUPS: dict[str, tuple[list[str], list[str], list[str]]] = {
    "verdicts": (["identification/common/metrics.py", "identification/validation/replay.py"],
                 ["tests/identification/common/test_metrics.py",
                  "tests/identification/common/test_skill_interval.py"], []),
    "config": (["fmu_models/config.py"],
               ["tests/fmu_models/test_config_schemas.py", "tests/fmu_models/test_params_schema.py"],
               ["-k", "not wrong_values"]),
    "codecs": (["hil_adapter/packets.py", "hil_adapter/mavlink_fast.py"],
               ["tests/hil_adapter/test_packet_codecs.py", "tests/hil_adapter/test_hil_mavlink_fast.py",
                "tests/hil_adapter/test_hil_ardupilot_json.py",
                "tests/hil_adapter/test_hil_packets.py"], []),
    "pwm": (["fmu_models/signals/pwm_mapping.py"], ["tests/fmu_models/test_pwm_mapping.py"], []),
    "sanitiser": (["identification/logs/flightlog.py"],
                  ["tests/identification/logs/test_readers.py", "tests/identification/logs/test_damaged_logs.py"], []),
}


def _toml_list(items: list[str]) -> str:
    return "[" + ", ".join(f'"{i}"' for i in items) + "]"


def _write_table(root: Path, group: str) -> None:
    """The repository's pyproject.toml with the group's ``[tool.mutmut]`` table, in the copy ``root``."""
    modules, tests, args = GROUPS[group]
    table = "\n".join([
        "[tool.mutmut]", 'source_paths = ["fmu_models", "identification", "hil_adapter", "uavfmu"]',
        f"only_mutate = {_toml_list(modules)}", 'also_copy = ["build_fmus.py", "autopilot"]',
        f"pytest_add_cli_args_test_selection = {_toml_list(tests)}",
        f"pytest_add_cli_args = {_toml_list(['-q', '-p', 'no:cacheprovider', *args])}", ""])
    text = re.sub(r"\n\[tool\.mutmut\]\n.*", "", (REPO / "pyproject.toml").read_text(), flags=re.S)
    (root / "pyproject.toml").write_text(text.rstrip("\n") + "\n\n" + table)


def prepare(group: str) -> Path:
    """A fresh copy of the tracked files with the group's ``[tool.mutmut]``; ``../shared`` linked beside it."""
    root = WORK / group
    shutil.rmtree(root, ignore_errors=True)
    files = subprocess.run(["git", "ls-files"], cwd=REPO, capture_output=True, text=True, check=True).stdout.split()
    for f in files:
        if (REPO / f).is_file():
            (root / f).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(REPO / f, root / f)
    _write_table(root, group)
    shared = REPO.parent / "shared"
    if shared.is_dir():  # tests find ../shared/data beside the copy that mutmut runs (root/mutants)
        (root / "shared").symlink_to(shared)
    return root


def run(group: str) -> int:
    root = prepare(group)
    env = {**os.environ, "UAVFMU_FUZZ_SCALE": "0.05"}
    mutmut = Path(sys.executable).with_name("mutmut")
    print(f"mutation: {group} ({', '.join(GROUPS[group][0])})", flush=True)
    with open(root / "mutmut.log", "w") as log:
        return subprocess.run([str(mutmut), "run", "--max-children", "2"], cwd=root, env=env, stdout=log,
                              stderr=subprocess.STDOUT).returncode


def rerun_survivors(group: str) -> int:
    """Run again, with the current tests, only the mutants of ``group`` that survived or had no test (tests only
    added since: what was killed stays killed)."""
    import json

    root = WORK / group
    for f in subprocess.run(["git", "ls-files", "tests"], cwd=REPO, capture_output=True, text=True,
                            check=True).stdout.split():
        (root / f).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO / f, root / f)
    _write_table(root, group)
    names = [k for mod in GROUPS[group][0]
             for k, code in json.loads((root / "mutants" / f"{mod}.meta").read_text())["exit_code_by_key"].items()
             if code in (0, 5, 33)]
    print(f"mutation: {group}, {len(names)} survivors again", flush=True)
    env = {**os.environ, "UAVFMU_FUZZ_SCALE": "0.05"}
    with open(root / "mutmut-rerun.log", "w") as log:
        return subprocess.run([str(Path(sys.executable).with_name("mutmut")), "run", "--max-children", "2", *names],
                              cwd=root, env=env, stdout=log, stderr=subprocess.STDOUT).returncode


def main(argv: list[str]) -> int:
    if argv[:1] == ["--survivors"]:
        for group in argv[1:]:
            rerun_survivors(group)
        return 0
    for group in argv or list(GROUPS):
        run(group)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
