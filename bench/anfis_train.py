"""Benchmark: our hybrid ANFIS training against anfis-toolbox's (PyPI), same data, one run each.

Problem: x ~ U(4800, 7200) us, y = 11.18 (x/6000)^2 + 0.2 N(0, 1) N, 5000 training and 2000 test
samples, seed 0, 6 Gaussian MFs, 100 epochs, hybrid learning (least squares + gradient descent).
anfis-toolbox's hybrid trainer has first-order consequents only, so it is compared with our first-order
run; our zero-order run (the paper's) is listed too. Prints wall times, the ratio against anfis-toolbox
measured in the same run, and the test RMSE of each. Target: >= 100x faster, test RMSE within 1 %; exit 1
when missed.

    .venv/bin/python bench/anfis_train.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from identification.thrust.anfis_train import AnfisTrainConfig, predict, rmse, train_anfis

SEED = 0
N_TRAIN, N_TEST = 5000, 2000
N_MFS, EPOCHS = 6, 100


def data() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(SEED)
    x = rng.uniform(4800.0, 7200.0, N_TRAIN + N_TEST)
    y = 11.18 * (x / 6000.0) ** 2 + 0.2 * rng.standard_normal(x.size)
    return x[:N_TRAIN], y[:N_TRAIN], x[N_TRAIN:], y[N_TRAIN:]


def ours(order: int, x: np.ndarray, y: np.ndarray, xt: np.ndarray, yt: np.ndarray) -> tuple[float, float]:
    t0 = time.perf_counter()
    res = train_anfis(x, y, AnfisTrainConfig(n_mfs=N_MFS, mf_type="gaussian", order=order, epochs=EPOCHS))
    wall = time.perf_counter() - t0
    return wall, rmse(predict(res.amap, xt), yt)


def toolbox(x: np.ndarray, y: np.ndarray, xt: np.ndarray, yt: np.ndarray) -> tuple[float, float]:
    from anfis_toolbox import ANFISRegressor

    np.random.seed(SEED)  # anfis-toolbox shuffles with numpy's global generator
    t0 = time.perf_counter()
    model = ANFISRegressor(
        n_mfs=N_MFS, mf_type="gaussian", init="grid", optimizer="hybrid", epochs=EPOCHS, random_state=SEED
    )
    model.fit(x[:, None], y)
    wall = time.perf_counter() - t0
    return wall, rmse(np.asarray(model.predict(xt[:, None])).ravel(), yt)


def main() -> int:
    x, y, xt, yt = data()
    try:
        ref_wall, ref_rmse = toolbox(x, y, xt, yt)
    except ImportError:
        print("anfis-toolbox is not installed: .venv/bin/pip install anfis-toolbox (bench extra)")
        return 1
    o1_wall, o1_rmse = ours(1, x, y, xt, yt)
    o0_wall, o0_rmse = ours(0, x, y, xt, yt)
    print(f"data: {N_TRAIN} train / {N_TEST} test, {N_MFS} Gaussian MFs, {EPOCHS} epochs, seed {SEED}")
    print(f"{'run':<34} {'wall [s]':>9} {'speed-up':>9} {'test RMSE [N]':>14} {'vs toolbox':>11}")
    rows = (
        ("anfis-toolbox hybrid (1st order)", ref_wall, ref_rmse),
        ("uavfmu hybrid, 1st order", o1_wall, o1_rmse),
        ("uavfmu hybrid, 0th order (paper)", o0_wall, o0_rmse),
    )
    for name, wall, err in rows:
        print(
            f"{name:<34} {wall:>9.3f} {ref_wall / wall:>8.1f}x {err:>14.4f} "
            f"{100 * (err / ref_rmse - 1):>+10.2f}%"
        )
    ok = ref_wall / o1_wall >= 100.0 and abs(o1_rmse / ref_rmse - 1.0) <= 0.01
    print(f"target (>= 100x, RMSE within 1 %, first order): {'met' if ok else 'NOT met'}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
