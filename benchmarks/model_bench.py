"""Speed of DP-TPU inference (onnxruntime) side by side with the classical unwrapping of the same input.

Run it as ``python benchmarks/model_bench.py [--model PATH] [--threads 2] [--size 480x640] [--runs 30]
[--json]`` or as ``dptpu bench model ...``. Not a test: nothing here asserts a time.

What is measured, in one run, on one synthetic input of ``--size`` (height x width, default 480x640):

- ``inference``: :meth:`dptpu.models.inference.FringeOrderModel.predict` of the model (default: the shipped
  ``dptpu/models/dptpu.onnx``) in an onnxruntime session with ``--threads`` intra-op threads (default 2,
  the issue's goal: <= 25 ms for 480x640 on 2 threads); the time of the ``session.run`` call plus the
  float32 conversion of the inputs, i.e. the network alone, without the classical order before it or the
  rounding after it;
- ``refine``: :meth:`~dptpu.models.inference.FringeOrderModel.refine` (masking, network, rounding), what
  ``dptpu unwrap`` adds to the classical unwrapping;
- ``classical``: :func:`dptpu.fpp.tpu.unwrap_mf` (Eq. (5) of the paper) of the same wrapped phases.

The input is an analytic step scene (:func:`dptpu.models.toy_dataset.toy_sample`, MF, ``f_h = 96``,
1 sigma noise, 3 steps). Each timing is ``--warmup`` untimed runs then ``--runs`` timed runs (wall clock,
``time.perf_counter``); the report gives p50 and p99 (nearest-rank) in milliseconds, interleaving the
three timings run by run so that a load spike of the shared machine hits all three alike, and the load
average of the machine at the start and end (``os.getloadavg``). ``*_cpu_ms_p50`` is the CPU time of the
process during the call (``time.process_time``, all threads summed): on a loaded machine it is closer to
what the call costs on idle cores than the wall clock (with 1 thread about equal to the idle wall time;
with 2 threads at best twice it).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time

import numpy as np

DEFAULT_SIZE = (480, 640)
DEFAULT_THREADS = 2
DEFAULT_RUNS = 30
DEFAULT_WARMUP = 3
FREQUENCY_HIGH = 96.0


def _size(text: str) -> tuple[int, int]:
    try:
        height, width = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--size must be HxW in pixels, e.g. 480x640; got {text!r}") from None
    if height < 1 or width < 1:
        raise argparse.ArgumentTypeError(f"--size must be positive; got {text!r}")
    return height, width


def _positive(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1; got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1; got {text!r}")
    return value


def percentile_ms(seconds: list[float], q: float) -> float:
    """Nearest-rank percentile ``q`` (0-100) of ``seconds``, in milliseconds."""
    ordered = np.sort(np.asarray(seconds, dtype=np.float64))
    rank = int(np.ceil(q / 100.0 * len(ordered))) - 1
    return float(ordered[min(max(rank, 0), len(ordered) - 1)] * 1e3)


def run(model_path, *, size=DEFAULT_SIZE, threads: int = DEFAULT_THREADS, runs: int = DEFAULT_RUNS,
        warmup: int = DEFAULT_WARMUP) -> dict:
    """Time inference, refine and ``unwrap_mf`` on one input; returns the report dict (see module doc)."""
    from dptpu.fpp.tpu import unwrap_mf
    from dptpu.models.inference import FringeOrderModel
    from dptpu.models.toy_dataset import toy_sample

    load_start = os.getloadavg()
    model = FringeOrderModel.load(model_path, threads=threads)
    sample = toy_sample("mf", FREQUENCY_HIGH, shape=tuple(size), noise_sigma=1.5693, scene_seed=12345)
    valid = sample["valid"]
    psi_h = np.where(valid, sample["wrapped_high"], np.nan).astype(np.float64)
    psi_l = np.where(valid, sample["wrapped_low"], np.nan).astype(np.float64)
    coarse = unwrap_mf(psi_h, psi_l, FREQUENCY_HIGH, 1.0, valid=valid).fringe_order.astype(np.float64)
    clean = [np.where(valid, a, 0.0) for a in (psi_h, psi_l, coarse)]

    def infer():
        return model.predict(*clean, FREQUENCY_HIGH)

    def refine():
        return model.refine(psi_h, psi_l, coarse, FREQUENCY_HIGH, valid=valid)

    def classical():
        return unwrap_mf(psi_h, psi_l, FREQUENCY_HIGH, 1.0, valid=valid)

    timings = {"inference": [], "refine": [], "classical": []}
    cpu = {"inference": [], "classical": []}
    functions = {"inference": infer, "refine": refine, "classical": classical}
    for _ in range(warmup):
        for function in functions.values():
            function()
    for _ in range(runs):
        for name, function in functions.items():
            start, start_cpu = time.perf_counter(), time.process_time()
            function()
            timings[name].append(time.perf_counter() - start)
            if name in cpu:
                cpu[name].append(time.process_time() - start_cpu)
    label = sample["label_order"]
    refined = refine()
    report = {
        "model": str(model_path), "kind": model.kind, "config": model.config, "size": list(size),
        "threads": threads, "runs": runs, "warmup": warmup,
        "inference_ms_p50": percentile_ms(timings["inference"], 50),
        "inference_ms_p99": percentile_ms(timings["inference"], 99),
        "refine_ms_p50": percentile_ms(timings["refine"], 50),
        "classical_ms_p50": percentile_ms(timings["classical"], 50),
        "classical_ms_p99": percentile_ms(timings["classical"], 99),
        "inference_cpu_ms_p50": percentile_ms(cpu["inference"], 50),
        "classical_cpu_ms_p50": percentile_ms(cpu["classical"], 50),
        "accuracy_classical": float(np.mean(coarse[valid] == label[valid])),
        "accuracy_model": float(np.mean(refined[valid] == label[valid])),
        "loadavg_start": [round(v, 2) for v in load_start],
        "loadavg_end": [round(v, 2) for v in os.getloadavg()],
        "cpu_count": os.cpu_count(), "python": platform.python_version(),
    }
    try:
        import onnxruntime

        report["onnxruntime"] = onnxruntime.__version__
    except ImportError:  # pragma: no cover - FringeOrderModel.load needs it
        pass
    return report


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="dptpu bench model", description="DP-TPU inference (onnxruntime) vs classical unwrap_mf, same input")
    parser.add_argument("--model", default=None, help="ONNX model (default: the shipped dptpu/models/dptpu.onnx)")
    parser.add_argument("--size", type=_size, default=DEFAULT_SIZE, metavar="HxW", help="input size (480x640)")
    parser.add_argument("--threads", type=_positive, default=DEFAULT_THREADS, help="onnxruntime intra-op threads")
    parser.add_argument("--runs", type=_positive, default=DEFAULT_RUNS, help="timed runs (default 30)")
    parser.add_argument("--warmup", type=int, default=DEFAULT_WARMUP, help="untimed runs first (default 3)")
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    args = parser.parse_args(argv)
    from dptpu.models.inference import ModelLoadError, shipped_model_path

    model_path = args.model or shipped_model_path()
    if model_path is None:
        print("no model: pass --model PATH (the package has no shipped dptpu/models/dptpu.onnx)", file=sys.stderr)
        return 2
    try:
        report = run(model_path, size=args.size, threads=args.threads, runs=args.runs, warmup=max(args.warmup, 0))
    except ModelLoadError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        h, w = report["size"]
        print(f"model {report['model']} ({report['kind']}), {h}x{w}, {report['threads']} threads, "
              f"{report['runs']} runs, load average {report['loadavg_start']} -> {report['loadavg_end']}")
        print(f"  inference  p50 {report['inference_ms_p50']:8.1f} ms   p99 {report['inference_ms_p99']:8.1f} ms"
              f"   CPU p50 {report['inference_cpu_ms_p50']:8.1f} ms")
        print(f"  refine     p50 {report['refine_ms_p50']:8.1f} ms")
        print(f"  classical  p50 {report['classical_ms_p50']:8.1f} ms   p99 {report['classical_ms_p99']:8.1f} ms"
              f"   CPU p50 {report['classical_cpu_ms_p50']:8.1f} ms   (unwrap_mf)")
        print(f"  accuracy   classical {100 * report['accuracy_classical']:.2f} %   "
              f"model {100 * report['accuracy_model']:.2f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
