"""Time one similarity test: a task segment (p deltas) against a demonstration feature.

Run: ``python benchmarks/bench_similarity.py [--num-samples 1000] [--p 4]``. Prints the
median wall time per :func:`drake_lfd.core.similarity.allocate_features` call. The planners
run this test for every (segment, demonstration) pair, so it should stay well under 1 ms
for a 1000-sample demonstration and p up to 4.
"""

from __future__ import annotations

import argparse
import timeit

import numpy as np

from drake_lfd.core.pose_conversions import dual_quaternion_from_euler_zyx
from drake_lfd.core.features import Feature, task_feature_from_poses
from drake_lfd.core.similarity import Tolerances, allocate_features

__all__ = ["main"]


def _demo_poses(num_raw):
    """A screwing-like demo: 0.1 m along tool z while turning -90 deg about it."""
    s = np.linspace(0.0, 1.0, num_raw)
    positions = np.stack([0.4 + 0 * s, 0.1 + 0 * s, 0.3 - 0.1 * s], axis=1)
    angles = np.stack([-0.5 * np.pi * s, np.pi + 0 * s, 0 * s], axis=1)
    return dual_quaternion_from_euler_zyx(positions, angles)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--num-samples", type=int, default=1000, help="demo deltas (n)")
    parser.add_argument("--p", type=int, default=4, help="task deltas in the segment")
    parser.add_argument("--repeats", type=int, default=2000)
    args = parser.parse_args(argv)

    demo = Feature.from_poses(_demo_poses(500), num_samples=args.num_samples + 1)
    s = np.linspace(0.0, 1.0, args.p + 1)
    task_poses = dual_quaternion_from_euler_zyx(
        np.stack([-0.2 + 0 * s, 0.3 + 0 * s, 0.5 - 0.3 * s], axis=1),
        np.stack([-0.5 * np.pi * s, np.pi + 0 * s, 0 * s], axis=1),
    )
    task = task_feature_from_poses(task_poses)
    tolerances = Tolerances()
    allocation = allocate_features(task, demo, tolerances)
    assert allocation is not None, "the benchmark segment should match the demo"

    times = timeit.repeat(lambda: allocate_features(task, demo, tolerances), number=1,
                          repeat=args.repeats)
    median_us = 1e6 * float(np.median(times))
    print(f"similarity test, p = {args.p}, n = {len(demo)} demo deltas: "
          f"median {median_us:.1f} us per segment test ({args.repeats} calls)")
    return median_us


if __name__ == "__main__":
    main()
