"""``python -m rattlefit.cli``: the command line."""

from . import main

main()
