"""What a person reads and looks at: text tables, PNG plots and the self-contained HTML
report of an identification, a posterior and a diagnosis."""

from .document import html_report, write_report
from .plots import plot_diagnosis, plot_fit, plot_igr, plot_posterior
from .tables import format_diagnosis, format_posterior, format_suggestions, format_table
from .wording import diagnosis_document, verdict_sentence

__all__ = [
    "diagnosis_document",
    "format_diagnosis",
    "format_posterior",
    "format_suggestions",
    "format_table",
    "html_report",
    "plot_diagnosis",
    "plot_fit",
    "plot_igr",
    "plot_posterior",
    "verdict_sentence",
    "write_report",
]
