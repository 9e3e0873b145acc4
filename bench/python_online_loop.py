#!/usr/bin/env python3
"""The navigation loop of examples/navigation_loop.cc driven from Python: read a data set,
feed every step's control and scan to RBPF local maps joined by the EIF, read the online
pose and its covariance after every step, print it every 10 s of data, finish, and print
the final pose. Timed against the C++ example, pair by pair (bench/RESULTS.md, "Python"):

    farm-bench -n 8 --vs 'build/examples/navigation_loop DATA' -- \\
        env PYTHONPATH=build/python /usr/bin/python3 bench/python_online_loop.py DATA
"""
import math
import sys

import subslam


def main(directory):
    dataset = subslam.read_dataset(directory)
    steps = dataset.steps()
    times, dts, controls, scans = steps["t"].tolist(), steps["dt"].tolist(), steps["u"], steps["scan"].tolist()
    slam = subslam.Slam(dataset, frontend="rbpf", backend="eif")
    next_print = times[0]
    for k, t in enumerate(times):
        slam.predict(controls[k], dts[k])
        if scans[k] >= 0:
            slam.update(**dataset.scan(scans[k]))
        slam.record_step(t)
        pose, covariance = slam.pose, slam.pose_covariance
        if t >= next_print:
            print(f"t {t:6.1f} s  pose ({pose[0]:7.2f}, {pose[1]:7.2f}, {pose[2]:6.3f})  "
                  f"position sd {math.sqrt(covariance[0, 0] + covariance[1, 1]):.2f} m")
            next_print += 10.0
    slam.finish()
    final = slam.final_trajectory()["poses"][-1]
    print(f"{len(slam.local_maps())} local maps joined into {len(slam.landmarks()['ids'])} landmarks; "
          f"final pose ({final[0]:.2f}, {final[1]:.2f}, {final[2]:.3f})")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(f"usage: {sys.argv[0]} DATASET_DIR")
    main(sys.argv[1])
