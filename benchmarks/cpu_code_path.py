"""Does forcing another CPU code path change float32 network training? (issue #36)

Trains rigmap's feed-forward network (``FeedForwardRegressor``, the NN rows' model) for a
few hundred Adam steps on fixed synthetic data with seed 0, once per environment, each in a
fresh process (the settings are read when torch loads), and prints JSON: per environment
the prediction checksum and the largest difference to the default run's predictions. A
non-zero difference means a second clone run with that environment is a fair stand-in for
"another machine" in ``scripts/seed_spread.py``.

    .venv/bin/python benchmarks/cpu_code_path.py [--steps 300]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

#: the environments tried (ours): each forces an older instruction set on one library
ENVIRONMENTS = {
    "default": {},
    "ATEN_CPU_CAPABILITY=default": {"ATEN_CPU_CAPABILITY": "default"},
    "ATEN_CPU_CAPABILITY=avx2": {"ATEN_CPU_CAPABILITY": "avx2"},
    "ONEDNN_MAX_CPU_ISA=SSE41": {"ONEDNN_MAX_CPU_ISA": "SSE41"},
    "MKL_ENABLE_INSTRUCTIONS=SSE4_2": {"MKL_ENABLE_INSTRUCTIONS": "SSE4_2"},
    "all four": {
        "ATEN_CPU_CAPABILITY": "default",
        "ONEDNN_MAX_CPU_ISA": "SSE41",
        "MKL_ENABLE_INSTRUCTIONS": "SSE4_2",
        "OPENBLAS_CORETYPE": "Prescott",
    },
}


def train(steps: int, out: Path) -> None:
    """One training run (in the child process): predictions saved to ``out``."""
    import torch

    from rigmap.regression.network import FeedForwardRegressor

    rng = np.random.default_rng(0)
    X = rng.normal(size=(steps * 8, 60))
    Y = np.tanh(X @ rng.normal(size=(60, 40)) / 8.0)
    model = FeedForwardRegressor(hidden=256, batch_size=8, epochs=1, seed=0, progress=False)
    model.fit(X, Y)
    np.save(out, model.predict(X[:200]))
    print(json.dumps({"capability": torch.backends.cpu.get_cpu_capability()}))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300, help="Adam steps (batch 8)")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if not 1 <= args.steps <= 100_000:
        parser.error(f"--steps: expected 1 to 100000, got {args.steps}")
    if args.child:
        train(args.steps, Path(args.child))
        return
    results, reference = {}, None
    with tempfile.TemporaryDirectory() as folder:
        for name, extra in ENVIRONMENTS.items():
            out = Path(folder) / f"{len(results)}.npy"
            env = {**os.environ, **extra}
            command = [sys.executable, __file__, "--steps", str(args.steps), "--child", str(out)]
            done = subprocess.run(command, env=env, capture_output=True, text=True, check=True)
            predictions = np.load(out)
            reference = predictions if reference is None else reference
            results[name] = {
                "env": extra,
                "torch_cpu_capability": json.loads(done.stdout.splitlines()[-1])["capability"],
                "prediction_sum": float(predictions.astype(np.float64).sum()),
                "max_abs_difference_to_default": float(np.abs(predictions - reference).max()),
            }
    print(json.dumps({"steps": args.steps, "environments": results}, indent=2))


if __name__ == "__main__":
    main()
