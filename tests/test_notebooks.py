"""Every notebook in ``notebooks/`` runs top to bottom in its short version.

Each ``notebooks/*.ipynb`` is executed in memory with nbclient (the committed file is never
written) in a kernel of the interpreter running the tests, with ``RATTLEFIT_NOTEBOOK_QUICK=1``
(the notebooks' parameter cells then choose short settings), the test run's compilation cache
(``RATTLEFIT_CACHE_DIR``, tests/conftest.py) and the notebooks folder as working directory.
The notebooks' own assert cells hold their results against the paper and against the
recordings' truth, so a notebook whose numbers drift fails here with the failing cell's
error.
"""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path

import nbformat
import pytest
from ipykernel.kernelspec import write_kernel_spec
from nbclient import NotebookClient
from nbclient.exceptions import CellExecutionError

import rattlefit

NOTEBOOKS = Path(__file__).resolve().parents[1] / "notebooks"
#: Generous: a full-settings cell runs for minutes; a quick one for well under one.
CELL_TIMEOUT_S = 900
KERNEL = "python3"


def kernel_env() -> dict[str, str]:
    """The kernel's environment: this one (the test run's compilation cache included), the
    notebooks' quick switch, one BLAS thread, and on the path the rattlefit the tests import
    first (a checkout's ``src`` or the installed package's folder) and these tests' helpers."""
    env = dict(os.environ)
    env["RATTLEFIT_NOTEBOOK_QUICK"] = "1"
    env["OPENBLAS_NUM_THREADS"] = "1"  # one BLAS thread beside the other pytest-xdist worker
    package_root = str(Path(rattlefit.__file__).resolve().parents[1])
    paths = (package_root, str(Path(__file__).parent), env.get("PYTHONPATH", ""))
    env["PYTHONPATH"] = os.pathsep.join(p for p in paths if p)
    return env


#: What the kernel runs before the notebook: JAX started on one CPU device with one thread in
#: XLA's pool, as in every test process (tests/conftest.py: pytest-xdist already runs one
#: worker per core). The notebook's ``rattlefit.configure()`` then keeps that device count, so
#: its compiled programs are the workers' own, taken from the test run's compilation cache
#: instead of compiled again for a layout no other test uses. The same seed gives the same fit
#: on any layout (tests/test_likelihood.py, tests/test_parallel.py).
KERNEL_START = "from xla_threads import start_jax_on_one_thread; start_jax_on_one_thread()"


@pytest.fixture
def own_kernel(tmp_path, monkeypatch):
    """A ``python3`` kernel spec that starts this interpreter (``sys.executable``) with
    :data:`KERNEL_START`, first on Jupyter's search path, so that the notebooks run in the
    test environment and not in a ``python3`` kernel registered elsewhere (the user's or the
    system's)."""
    write_kernel_spec(
        str(tmp_path / "kernels" / KERNEL),
        extra_arguments=[f"--IPKernelApp.exec_lines={KERNEL_START}"],
    )
    monkeypatch.setenv("JUPYTER_PATH", str(tmp_path))
    return sys.executable


@pytest.mark.parametrize("notebook", sorted(NOTEBOOKS.glob("*.ipynb")), ids=lambda p: p.stem)
def test_notebook_runs(notebook: Path, own_kernel):
    nb = nbformat.read(notebook, as_version=4)
    client = NotebookClient(
        nb,
        kernel_name=KERNEL,
        timeout=CELL_TIMEOUT_S,
        resources={"metadata": {"path": str(NOTEBOOKS)}},
    )
    failure = None
    try:
        client.execute(env=kernel_env())
    except CellExecutionError as err:
        # the kernel colours its traceback; the report is read as plain text
        failure = re.sub(r"\x1b\[[0-9;]*m", "", str(err))
    if failure is not None:  # outside the except block: the cell's error alone, unchained
        pytest.fail(f"{notebook.name}: a cell failed\n{failure}", pytrace=False)


def test_notebooks_exist():
    """The glob above finds the notebooks (an empty parametrisation would pass silently)."""
    assert sorted(NOTEBOOKS.glob("*.ipynb")), f"no notebooks in {NOTEBOOKS}"
