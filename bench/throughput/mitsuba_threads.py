#!/usr/bin/env python3
"""Runs ../shared/anchors/mitsuba/run_mitsuba.py with Dr.Jit's thread pool set to N threads, for
bench/throughput.py (the harness itself uses Dr.Jit's default, one thread per core):

    python3 mitsuba_threads.py N path/to/run_mitsuba.py rays --scene quadrics --variant llvm_ad_rgb
"""
import runpy
import sys

if len(sys.argv) < 3:
    raise SystemExit(__doc__)
threads, harness = int(sys.argv[1]), sys.argv[2]
import drjit as dr  # noqa: E402

dr.set_thread_count(threads)
sys.argv = [harness] + sys.argv[3:]
runpy.run_path(harness, run_name="__main__")
