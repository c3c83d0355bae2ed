"""Where the commands write: checks made before the work, so that a command that cannot finish writes nothing.

`check_writable(path)` fails when `path` cannot be created; `check_replaceable(out, ...)` when an existing
output directory is not one that the same command wrote (compare's and export's, which replace theirs whole).
"""

from __future__ import annotations

import json
import tempfile
from collections.abc import Callable
from pathlib import Path

from prefilter import PrefilterError


def check_writable(path: Path) -> None:
    """Fail before any rendering when `path` cannot be written: a file is created and removed at once in the
    nearest directory of its that exists (the writers make the missing ones)."""
    ancestor = path.absolute().parent
    while not ancestor.exists():
        ancestor = ancestor.parent
    try:
        with tempfile.TemporaryFile(dir=ancestor):
            pass
    except OSError as exc:
        raise PrefilterError(f"{path}: cannot write in {ancestor} ({exc.strerror or exc})") from None


def check_replaceable(out: Path, marker: str, is_ours: Callable[[object], bool], what: str) -> None:
    """`out` may be replaced whole: it does not exist, is an empty directory, or its JSON file `marker`
    satisfies `is_ours` (an earlier output of the same kind). Anything else is refused, as it would be
    deleted."""
    if not out.exists():
        return
    try:
        ours = bool(is_ours(json.loads((out / marker).read_text())))
    except (OSError, ValueError, TypeError, AttributeError):  # no marker, not JSON, or not of this shape
        ours = False
    if not ours and (not out.is_dir() or any(out.iterdir())):
        raise PrefilterError(f"{out}: exists and is not {what}; choose another -o directory")
