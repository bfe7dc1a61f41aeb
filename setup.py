"""Maps the user's folder names to non-generic import names (the Layout section of README.md).

``framework/`` installs as ``trackfw`` and ``plugins/`` as ``trackfw_plugins``. Sub-packages are
discovered here so that a new plugin folder needs no packaging change.
"""

from pathlib import Path

from setuptools import setup

ROOTS = {"trackfw": "framework", "trackfw_plugins": "plugins"}


def discover() -> list[str]:
    packages = []
    for import_name, folder in ROOTS.items():
        for init in sorted(Path(folder).rglob("__init__.py")):
            relative = init.parent.relative_to(folder)
            packages.append(".".join((import_name, *relative.parts)))
    return packages


setup(packages=discover(), package_dir=ROOTS)
