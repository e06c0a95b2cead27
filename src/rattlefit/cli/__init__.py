"""The ``rattlefit`` command line: parse → library call → print or write JSON.

One module per command group (:mod:`.recording`: ``info``, ``import``, ``simulate``;
:mod:`.identify`, :mod:`.sample`, :mod:`.diagnose`, :mod:`.report`, :mod:`.campaign`), the
options several of them take declared once in :mod:`.common`. Every library error
(:class:`~rattlefit.errors.RattlefitError`), and every file the OS will not read or write,
becomes one line on stderr, ``rattlefit: error: <file>: <field>: <problem>``, and exit status
2; nothing is half-written because every output goes through a temporary file that is renamed
into place. Starting the command line loads neither JAX nor SciPy: a command configures JAX
when it runs, and numpy's kernels are kept below AVX-512 before it is loaded
(:func:`~rattlefit.reproducibility.cap_numpy_simd`).
"""

from __future__ import annotations

import click

from ..reproducibility import cap_numpy_simd
from .campaign import campaign
from .diagnose import diagnose
from .identify import identify
from .recording import import_, info, simulate
from .report import report
from .sample import sample


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="rattlefit")
def main() -> None:
    """Identify the physics of idle gear rattle from encoder recordings."""
    cap_numpy_simd()  # before a command imports numpy, as configure() caps XLA


for command in (info, import_, simulate, identify, sample, diagnose, report, campaign):
    main.add_command(command)

__all__ = ["main"]
