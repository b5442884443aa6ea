"""Speed of DP-TPU inference (onnxruntime) side by side with the classical unwrapping of the same input.

Run it as ``python benchmarks/model_bench.py [--model PATH] [--baseline PATH] [--threads 2] [--size 480x640]
[--runs 30] [--json]`` or as ``dptpu bench model ...``. Not a test: nothing here asserts a time.

What is measured, in one run, on one synthetic input of ``--size`` (height x width, default 480x640):

- ``inference``: :meth:`dptpu.models.inference.FringeOrderModel.predict` of the model (default: the shipped
  ``models/dptpu.onnx``) in an onnxruntime session with ``--threads`` intra-op threads (default 2,
  the issue's goal: <= 25 ms for 480x640 on 2 threads) on float32 maps that are already masked (what the
  float32 unwrapping of the scanner delivers), i.e. the network alone: the ``session.run`` call, without
  the classical order before it or the rounding after it;
- ``refine``: :meth:`~dptpu.models.inference.FringeOrderModel.refine` of float64 phase maps with NaN outside
  the mask and the int32 classical order (masking, float32 casts, network, rounding), as
  :func:`dptpu.models.refine.refine_capture_result` calls it for ``dptpu unwrap``;
- ``classical``: :func:`dptpu.fpp.tpu.unwrap_mf` (Eq. (5) of the paper) of the same wrapped phases;
- with ``--baseline PATH``, ``baseline_inference`` too: the same inference of a second model file (e.g. the
  same weights in the traced graph, :func:`dptpu.models.onnx_weights.convert_onnx`), interleaved run by run.

The input is an analytic step scene (:func:`dptpu.models.toy_dataset.toy_sample`, MF, ``f_h = 96``,
1 sigma noise, 3 steps). Each timing is ``--warmup`` untimed runs then ``--runs`` timed runs (wall clock,
``time.perf_counter``); the report gives p50 and p99 (nearest-rank) in milliseconds, interleaving the
timings run by run so that a load spike of the shared machine hits all of them alike, and the load
average of the machine at the start and end (``os.getloadavg``). ``*_cpu_ms_p50`` is the CPU time of the
process during the call (``time.process_time``, all threads summed): on a loaded machine it is closer to
what the call costs on idle cores than the wall clock (with 1 thread about equal to the idle wall time;
with 2 threads at best twice it). ``*_ms_min`` (the fastest run) is what an idle machine would show.
``--profile`` adds onnxruntime's per-node profile (:func:`profile`): the sum over the graph's kernels of each
one's fastest time, robust against the load of a shared machine, and that sum per op type.
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


def _graph(path) -> str:
    """The ``graph`` metadata of a model file (``"torch"`` for a traced export, which has none)."""
    import onnxruntime

    options = onnxruntime.SessionOptions()
    options.log_severity_level = 3
    session = onnxruntime.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
    return session.get_modelmeta().custom_metadata_map.get("graph", "torch")


def profile(model_path, *, size=DEFAULT_SIZE, threads: int = 1, runs: int = 40, skip: int = 5) -> dict:
    """onnxruntime's per-node profile of ``runs`` runs on random maps: each node's fastest kernel time after
    ``skip`` runs, summed per op type (a load-robust floor of the network's cost on an idle core).

    Returns ``{"profile_nodes": kernels per run, "profile_sum_of_minima_ms": ..., "profile_by_op_ms": {op: ms}}``.
    """
    import collections
    import tempfile

    import onnxruntime

    options = onnxruntime.SessionOptions()
    options.intra_op_num_threads = threads
    options.log_severity_level = 3
    options.add_session_config_entry("session.intra_op.allow_spinning", "0")
    options.enable_profiling = True
    with tempfile.TemporaryDirectory() as folder:
        options.profile_file_prefix = os.path.join(folder, "model")
        session = onnxruntime.InferenceSession(str(model_path), options, providers=["CPUExecutionProvider"])
        rng = np.random.default_rng(0)
        shape = (1, 1, *size)
        feeds = {"wrapped_high": rng.uniform(0, 2 * np.pi, shape).astype(np.float32),
                 "wrapped_low": rng.uniform(0, 2 * np.pi, shape).astype(np.float32),
                 "coarse_order": rng.integers(0, int(FREQUENCY_HIGH), shape).astype(np.float32),
                 "frequency_high": np.array([FREQUENCY_HIGH], np.float32)}
        feeds = {i.name: feeds[i.name] for i in session.get_inputs()}
        for _ in range(runs):
            session.run(None, feeds)
        with open(session.end_profiling()) as handle:
            events = json.load(handle)
    durations, op_types = collections.defaultdict(list), {}
    for event in events:
        if event.get("cat") == "Node" and event["name"].endswith("_kernel_time"):
            durations[event["name"]].append(event["dur"])
            op_types[event["name"]] = event["args"]["op_name"]
    minima = {name: min(values[skip:] or values) / 1e3 for name, values in durations.items()}
    by_op = collections.defaultdict(float)
    for name, ms in minima.items():
        by_op[op_types[name]] += ms
    return {"profile_nodes": len(minima), "profile_sum_of_minima_ms": round(sum(minima.values()), 3),
            "profile_by_op_ms": {op: round(ms, 3) for op, ms in sorted(by_op.items(), key=lambda x: -x[1])}}


def run(model_path, *, size=DEFAULT_SIZE, threads: int = DEFAULT_THREADS, runs: int = DEFAULT_RUNS,
        warmup: int = DEFAULT_WARMUP, baseline=None, spinning: bool = False) -> dict:
    """Time inference, refine and ``unwrap_mf`` on one input; returns the report dict (see module doc)."""
    from dptpu.fpp.tpu import unwrap_mf
    from dptpu.models.inference import FringeOrderModel
    from dptpu.models.toy_dataset import toy_sample

    load_start = os.getloadavg()
    model = FringeOrderModel.load(model_path, threads=threads, spinning=spinning)
    other = FringeOrderModel.load(baseline, threads=threads, spinning=spinning) if baseline is not None else None
    sample = toy_sample("mf", FREQUENCY_HIGH, shape=tuple(size), noise_sigma=1.5693, scene_seed=12345)
    valid = sample["valid"]
    psi_h = np.where(valid, sample["wrapped_high"], np.nan).astype(np.float64)
    psi_l = np.where(valid, sample["wrapped_low"], np.nan).astype(np.float64)
    coarse_order = unwrap_mf(psi_h, psi_l, FREQUENCY_HIGH, 1.0, valid=valid).fringe_order  # int32, as unwrap gives
    coarse = coarse_order.astype(np.float64)
    clean = [np.where(valid, a, 0.0).astype(np.float32) for a in (psi_h, psi_l, coarse)]

    functions = {
        "inference": lambda: model.predict(*clean, FREQUENCY_HIGH),
        "refine": lambda: model.refine(psi_h, psi_l, coarse_order, FREQUENCY_HIGH, valid=valid),
        "classical": lambda: unwrap_mf(psi_h, psi_l, FREQUENCY_HIGH, 1.0, valid=valid),
    }
    if other is not None:
        functions["baseline_inference"] = lambda: other.predict(*clean, FREQUENCY_HIGH)
    timings = {name: [] for name in functions}
    cpu = {name: [] for name in functions}
    for _ in range(warmup):
        for function in functions.values():
            function()
    for _ in range(runs):
        for name, function in functions.items():
            start, start_cpu = time.perf_counter(), time.process_time()
            function()
            timings[name].append(time.perf_counter() - start)
            cpu[name].append(time.process_time() - start_cpu)
    label = sample["label_order"]
    refined = functions["refine"]()
    report = {
        "model": str(model_path), "kind": model.kind, "graph": _graph(model_path), "config": model.config,
        "size": list(size), "threads": threads, "spinning": spinning, "runs": runs, "warmup": warmup,
        "inference_ms_p50": percentile_ms(timings["inference"], 50),
        "inference_ms_p99": percentile_ms(timings["inference"], 99),
        "inference_ms_min": percentile_ms(timings["inference"], 0),
        "refine_ms_p50": percentile_ms(timings["refine"], 50),
        "classical_ms_p50": percentile_ms(timings["classical"], 50),
        "classical_ms_p99": percentile_ms(timings["classical"], 99),
        "classical_ms_min": percentile_ms(timings["classical"], 0),
        "inference_cpu_ms_p50": percentile_ms(cpu["inference"], 50),
        "refine_cpu_ms_p50": percentile_ms(cpu["refine"], 50),
        "classical_cpu_ms_p50": percentile_ms(cpu["classical"], 50),
        "accuracy_classical": float(np.mean(coarse[valid] == label[valid])),
        "accuracy_model": float(np.mean(refined[valid] == label[valid])),
    }
    if other is not None:
        continuous = model.predict(*clean, FREQUENCY_HIGH)
        reference = other.predict(*clean, FREQUENCY_HIGH)
        report.update({
            "baseline": str(baseline), "baseline_graph": _graph(baseline),
            "baseline_inference_ms_p50": percentile_ms(timings["baseline_inference"], 50),
            "baseline_inference_ms_p99": percentile_ms(timings["baseline_inference"], 99),
            "baseline_inference_ms_min": percentile_ms(timings["baseline_inference"], 0),
            "baseline_inference_cpu_ms_p50": percentile_ms(cpu["baseline_inference"], 50),
            "baseline_max_abs_difference": float(np.max(np.abs(continuous - reference)[valid])),
        })
    report.update({
        "loadavg_start": [round(v, 2) for v in load_start],
        "loadavg_end": [round(v, 2) for v in os.getloadavg()],
        "cpu_count": os.cpu_count(), "python": platform.python_version(),
    })
    try:
        import onnxruntime

        report["onnxruntime"] = onnxruntime.__version__
    except ImportError:  # pragma: no cover - FringeOrderModel.load needs it
        pass
    return report


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="dptpu bench model", description="DP-TPU inference (onnxruntime) vs classical unwrap_mf, same input")
    parser.add_argument("--model", default=None, help="ONNX model (default: the shipped models/dptpu.onnx)")
    parser.add_argument("--baseline", default=None, metavar="PATH",
                        help="a second ONNX model whose inference is timed alongside (e.g. the traced graph)")
    parser.add_argument("--size", type=_size, default=DEFAULT_SIZE, metavar="HxW", help="input size (480x640)")
    parser.add_argument("--threads", type=_positive, default=DEFAULT_THREADS, help="onnxruntime intra-op threads")
    parser.add_argument("--spinning", action="store_true",
                        help="let idle onnxruntime threads spin (FringeOrderModel.load(spinning=True)); "
                             "idle machines only")
    parser.add_argument("--runs", type=_positive, default=DEFAULT_RUNS, help="timed runs (default 30)")
    parser.add_argument("--warmup", type=int, default=DEFAULT_WARMUP, help="untimed runs first (default 3)")
    parser.add_argument("--profile", action="store_true",
                        help="also onnxruntime's per-node profile (1 thread): sum of per-node minima by op")
    parser.add_argument("--profile-runs", type=_positive, default=40, help="profiled runs, the first 5 untimed (40)")
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    args = parser.parse_args(argv)
    from dptpu.models.inference import ModelLoadError, shipped_model_path

    model_path = args.model or shipped_model_path()
    if model_path is None:
        print("no model: pass --model PATH (the package has no shipped models/dptpu.onnx)", file=sys.stderr)
        return 2
    try:
        report = run(model_path, size=args.size, threads=args.threads, runs=args.runs, warmup=max(args.warmup, 0),
                     baseline=args.baseline, spinning=args.spinning)
        if args.profile:
            report.update(profile(model_path, size=args.size, runs=args.profile_runs))
            if args.baseline:
                report.update({f"baseline_{k}": v
                               for k, v in profile(args.baseline, size=args.size, runs=args.profile_runs).items()})
    except ModelLoadError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        h, w = report["size"]
        print(f"model {report['model']} ({report['kind']}, graph {report['graph']}), {h}x{w}, "
              f"{report['threads']} threads{' (spinning)' if report['spinning'] else ''}, "
              f"{report['runs']} runs, load average {report['loadavg_start']} -> {report['loadavg_end']}")
        print(f"  inference  p50 {report['inference_ms_p50']:8.1f} ms   p99 {report['inference_ms_p99']:8.1f} ms"
              f"   CPU p50 {report['inference_cpu_ms_p50']:8.1f} ms   min {report['inference_ms_min']:8.1f} ms")
        if "baseline" in report:
            print(f"  baseline   p50 {report['baseline_inference_ms_p50']:8.1f} ms   p99 "
                  f"{report['baseline_inference_ms_p99']:8.1f} ms   CPU p50 "
                  f"{report['baseline_inference_cpu_ms_p50']:8.1f} ms   min "
                  f"{report['baseline_inference_ms_min']:8.1f} ms   ({report['baseline']}, graph "
                  f"{report['baseline_graph']}; max |difference| {report['baseline_max_abs_difference']:.2g} orders)")
        print(f"  refine     p50 {report['refine_ms_p50']:8.1f} ms   CPU p50 {report['refine_cpu_ms_p50']:8.1f} ms")
        print(f"  classical  p50 {report['classical_ms_p50']:8.1f} ms   p99 {report['classical_ms_p99']:8.1f} ms"
              f"   CPU p50 {report['classical_cpu_ms_p50']:8.1f} ms   (unwrap_mf)")
        print(f"  accuracy   classical {100 * report['accuracy_classical']:.2f} %   "
              f"model {100 * report['accuracy_model']:.2f} %")
        for prefix in ("", "baseline_"):
            if f"{prefix}profile_nodes" in report:
                top = ", ".join(f"{op} {ms:.2f}" for op, ms in list(report[f"{prefix}profile_by_op_ms"].items())[:8])
                print(f"  {prefix or 'model '}profile: {report[f'{prefix}profile_nodes']} kernels, sum of per-node "
                      f"minima {report[f'{prefix}profile_sum_of_minima_ms']:.2f} ms (1 thread): {top}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
