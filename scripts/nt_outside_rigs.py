"""NT's fringe-order accuracy on rigs outside the training distribution (issue 16): classical and DP-TPU.

    .venv/bin/python scripts/nt_outside_rigs.py [--size 320x240] [--rigs 6] [--scenes 2]
        [--frequencies 64,88,96] [--noise 3.1386] [--steps 3]

For the outside tester's rig of issue 16 and ``--rigs`` random outside rigs (:mod:`dptpu.sim.outside_rigs`: focal
length, baseline, toe-in, projector panel and distortion drawn by a seed), ``--scenes`` scenes each (spheres before a
tilted plane, 3x3 supersampled: mixed pixels at the depth edges), ``--steps``-step fringes at ``--noise`` DN (the
paper's 2 sigma: 3.1386) with ``f_l = 10.9``: the share of pixels (lit, modulation > 5.1 DN in both sequences) whose
order of ``f_h`` is right, for the classical NT (:func:`dptpu.fpp.tpu.unwrap_nt`) and for DP-TPU with the shipped
model (:func:`dptpu.models.refine.refine_order`, NT through its band prior). Prints a Markdown table
(docs/model-eval.md, "Outside rigs (issue 16)").
"""
from __future__ import annotations

import argparse
import sys

import numpy as np

from dptpu.fpp import tpu
from dptpu.models.inference import FringeOrderModel, shipped_model_path
from dptpu.models.refine import refine_order
from dptpu.sim import outside_rigs

F_L = 10.9
MIN_MODULATION_DN = 5.1


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="320x240")
    parser.add_argument("--rigs", type=int, default=6)
    parser.add_argument("--scenes", type=int, default=2)
    parser.add_argument("--frequencies", default="64,88,96")
    parser.add_argument("--noise", type=float, default=outside_rigs.SIGMA_2)
    parser.add_argument("--steps", type=int, default=3)
    args = parser.parse_args(argv)
    try:
        size = tuple(int(v) for v in args.size.lower().split("x"))
        frequencies = [float(f) for f in args.frequencies.split(",")]
    except ValueError:
        print(f"error: --size WIDTHxHEIGHT and --frequencies F,F,...; got {args.size!r}, {args.frequencies!r}",
              file=sys.stderr)
        return 2
    path = shipped_model_path()
    if path is None:
        print("error: no shipped model (models/dptpu.onnx)", file=sys.stderr)
        return 2
    model = FringeOrderModel.load(path)
    rigs = [("issue 16 (1800 px, 150 mm, 14 deg)", outside_rigs.issue16_rig(size))]
    rigs += [(f"random {seed}", outside_rigs.random_outside_rig(seed, size)) for seed in range(args.rigs)]
    print("| rig | camera f (px at 640) | baseline (mm) | toe-in (deg) | projector | scene | "
          + " | ".join(f"f_h = {f:g}: classical / DP-TPU %" for f in frequencies) + " |")
    print("|" + "---|" * (6 + len(frequencies)))
    results: dict = {f: [] for f in frequencies}
    for name, rig in rigs:
        baseline = float(np.linalg.norm(rig.projector.center - rig.camera.center))
        angle = float(np.degrees(np.arccos(np.clip(rig.projector.R[2] @ rig.camera.R[2], -1.0, 1.0))))
        focal = rig.camera.K[0, 0] * 640.0 / rig.camera.size[0]
        for scene_seed in range(args.scenes):
            scene = outside_rigs.spheres_and_plane(rig, scene_seed, spheres=2 + scene_seed % 2)
            capture = outside_rigs.render_phases(rig, scene, frequencies + [F_L], steps=args.steps,
                                                 noise_dn=args.noise, seed=scene_seed)
            cells = []
            for f_h in frequencies:
                psi_h, psi_l = capture.phases[f_h], capture.phases[F_L]
                valid = capture.valid & (capture.modulation[f_h] > MIN_MODULATION_DN) & \
                    (capture.modulation[F_L] > MIN_MODULATION_DN)
                truth = capture.order(f_h)
                classical = tpu.unwrap_nt(psi_h, psi_l, f_h, F_L, capture.extent, valid=valid)
                order = refine_order(model, "nt", psi_h, psi_l, classical.fringe_order, f_h, F_L, valid,
                                     classical_valid=classical.valid)
                right = [100.0 * np.count_nonzero((k == truth) & valid) / np.count_nonzero(valid)
                         for k in (classical.fringe_order, order)]
                results[f_h].append(right[1])
                cells.append(f"{right[0]:.2f} / {right[1]:.2f}")
            print(f"| {name} | {focal:.0f} | {baseline:.0f} | {angle:.1f} | {rig.projector.size[0]}x"
                  f"{rig.projector.size[1]} | {len(scene.meshes) - 1} spheres, seed {scene_seed} | "
                  + " | ".join(cells) + " |", flush=True)
    print("\nDP-TPU, mean (lowest): " + ", ".join(f"f_h = {f:g}: {np.mean(v):.2f} ({np.min(v):.2f})"
                                              for f, v in results.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
