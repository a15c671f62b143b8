"""Set-up of evtms's local dask worker processes (a dask preload module).

A Ctrl-C in a terminal reaches every process of its group. The main process
handles it (it keeps the saved chunks, says how to resume and closes the
cluster); a worker that handled it too would print its own traceback. Each
local worker therefore ignores SIGINT once it has started; the main process
stops it when it closes the cluster.
"""

from __future__ import annotations

import signal


def dask_setup(worker: object) -> None:
    """Called by dask in each worker process as it starts (``distributed.worker.preload``)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
