"""prefilter: rendering non-linear appearance without aliasing, judged against supersampled ground truth."""

__version__ = "0.1.0"


class PrefilterError(Exception):
    """An error the user can act on; the CLI prints it as one line and exits non-zero."""
