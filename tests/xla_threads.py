"""Start JAX with one thread in XLA's CPU pool, in a process that may run on every core.

pytest-xdist already runs one worker per core, and each worker runs its simulations on one
JAX device. XLA's CPU client still sizes its intra-op thread pool by the CPUs the process may
run on when the client starts, so two workers on two cores would each run two pool threads
that take turns with each other's. :func:`start_jax_on_one_thread` configures rattlefit on one
device and starts the client while the process may run on one CPU, then gives every thread of
the process all of them back, so the operating system can still move the worker to whichever
core is idle. Every test process starts so: the workers (tests/conftest.py), the notebook
kernels and the campaign's dask workers (:func:`dask_setup`).
"""

from __future__ import annotations

import os
from pathlib import Path

import jax

import rattlefit as rf


def start_jax_on_one_thread() -> None:
    """:func:`rattlefit.configure` on one CPU device, then start JAX's backends with a
    one-thread XLA CPU pool (call it before anything else uses JAX). The pool's size needs
    Linux; elsewhere JAX starts as usual."""
    rf.configure(cpu_cores=1)
    if not hasattr(os, "sched_setaffinity"):  # pragma: no cover - not on Linux
        jax.devices()
        return
    every = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {min(every)})
    try:
        jax.devices()
    finally:
        for task in Path("/proc/self/task").iterdir():
            try:
                os.sched_setaffinity(int(task.name), every)
            except OSError:  # a thread that has ended since the listing
                pass


def pool_threads() -> int:
    """How many threads of this process are XLA's CPU pool (named ``tf_XLAEigen``)."""
    names = (task / "comm" for task in Path("/proc/self/task").iterdir())
    return sum(1 for name in names if name.read_text().strip() == "tf_XLAEigen")


def dask_setup(worker) -> None:
    """As a dask worker's preload (this file's path in ``preload=``): start JAX as every test
    process does before the worker runs a task; the campaign's own ``configure`` then finds
    the settings in effect."""
    start_jax_on_one_thread()
