"""trackfw: track people through head-worn-camera video across info-less intervals.

The core package holds the records, the stage interfaces, the plugin registry, the pipeline
loader and the online engine. Every algorithm lives in a plugin (``trackfw_plugins`` for the
built-ins), registered through the ``trackfw`` entry-point group.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("trackfw")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0.0.0+unknown"

#: Version of the plugin API. A plugin module may declare ``TRACKFW_PLUGIN_API``; a plugin
#: built for another major version is reported and skipped rather than half-working.
PLUGIN_API_VERSION = 1

__all__ = ["PLUGIN_API_VERSION", "__version__"]
