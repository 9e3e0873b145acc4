#!/usr/bin/env python3
"""Two simulated worlds run from two Python threads against the same two runs one after
the other: subslam.run releases the GIL, so on two cores the pair should take little more
than one run (bench/RESULTS.md, "Python"). Each run is on one thread, as a study runs them:
RBPF local maps (threads=1) joined by the EIF as each closes (join_in_background=False).

    PYTHONPATH=build/python /usr/bin/python3 bench/python_threads.py [--repeats N] [--scenario S]
"""
import argparse
import statistics
import threading
import time

import subslam


def one_run(scenario, seed):
    return subslam.run(scenario=scenario, seed=seed, frontend="rbpf", backend="eif", threads=1,
                       join_in_background=False)


def sequential(scenario):
    start = time.perf_counter()
    for seed in (1, 2):
        one_run(scenario, seed)
    return time.perf_counter() - start


def threaded(scenario):
    threads = [threading.Thread(target=one_run, args=(scenario, seed)) for seed in (1, 2)]
    start = time.perf_counter()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return time.perf_counter() - start


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--scenario", default="combined-2km")
    args = parser.parse_args()
    one_run(args.scenario, 1)  # warm: the first run pays the page faults of the libraries
    ratios = []
    for _ in range(args.repeats):  # pair by pair: a noisy machine slows both alike
        one_after_other, together = sequential(args.scenario), threaded(args.scenario)
        ratios.append(together / one_after_other)
        print(f"one after the other {one_after_other:.3f} s, two threads {together:.3f} s, "
              f"ratio {ratios[-1]:.3f}")
    print(f"median ratio {statistics.median(ratios):.3f} (min {min(ratios):.3f}, max {max(ratios):.3f})")


if __name__ == "__main__":
    main()
