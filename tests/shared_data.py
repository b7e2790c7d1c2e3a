"""Where the shared logs are: ``$FUZZYPOS_DATA``, else ``../shared/data`` beside the
repository (where CI and the workplace keep them); tests that need them skip where absent."""

from __future__ import annotations

import os
from pathlib import Path

DATA = Path(os.environ.get("FUZZYPOS_DATA") or Path(__file__).resolve().parents[1].parent / "shared" / "data")
