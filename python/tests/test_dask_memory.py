"""qota.dask's estimate of a task's memory (the result's attrs["qota_task_memory"]) against the
peak resident memory of one task computed in a process of its own (a module apart from
test_dask.py, so that no cluster of its shares the machine while the peaks are measured)."""
import os
import subprocess
import sys

import pytest

from test_interop import DATA, RAINIER

pytest.importorskip("rioxarray")
pytest.importorskip("dask.array")

TASK_PEAK = """
import sys, dask, rioxarray, qota.dask
dask.config.set(scheduler="synchronous")
mask = qota.dask.shadow(rioxarray.open_rasterio(sys.argv[1], chunks=int(sys.argv[2])), 135, float(sys.argv[3]))
# (VmHWM, not getrusage's ru_maxrss, which a process keeps from the parent it was forked from)
status = lambda key: next(int(l.split()[1]) * 1024 for l in open("/proc/self/status") if l.startswith(key))
before = status("VmRSS:")
mask.values
print(status("VmHWM:") - before, mask.attrs["qota_task_memory"])
"""


@pytest.mark.parametrize("dem,chunks,altitude", [(RAINIER, 1201, 2), (RAINIER, 1201, 45), (DATA / "SainteHelens.dem", 468, 10)])
def test_a_tasks_memory_estimate_bounds_its_peak(dem, chunks, altitude):
    # One task (the raster in one block) in a process of its own: its peak resident memory
    # against the estimate the result carries (attrs["qota_task_memory"]).
    env = {k: v for k, v in os.environ.items() if not k.startswith(("DASK_", "MALLOC_"))}
    out = subprocess.run([sys.executable, "-c", TASK_PEAK, str(dem), str(chunks), str(altitude)], check=True,
                         capture_output=True, text=True, env=env).stdout.split()
    peak, estimate = int(out[0]), int(out[1])
    assert peak <= estimate <= 1.5 * peak, (peak, estimate)
