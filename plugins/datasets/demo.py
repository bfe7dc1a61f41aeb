"""``builtin:demo``: a short synthetic clip, generated deterministically on first use.

No file is downloaded: the clip is rendered by the synthetic generator into the user's cache
(``$TRACKFW_CACHE`` or ``~/.cache/trackfw``) and reused afterwards.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

#: Bump when the demo's content changes, so stale caches are regenerated.
DEMO_VERSION = 1


def cache_root() -> Path:
    """Folder where generated inputs are kept."""
    configured = os.environ.get("TRACKFW_CACHE")
    if configured:
        return Path(configured).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "trackfw"


def demo_path() -> Path:
    """The demo video folder, rendered on first use (a few seconds)."""
    from trackfw_plugins.datasets.synth import generate_demo

    target = cache_root() / f"demo-v{DEMO_VERSION}" / "demo"
    if (target / "meta.json").is_file():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=".demo-", dir=target.parent))
    try:
        video = generate_demo(staging)
        if target.exists():  # another process finished first
            return target
        os.replace(video, target)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return target
