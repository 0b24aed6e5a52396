"""Package discovery for the two source roots (metadata lives in pyproject.toml).

shared/cbgo/ installs as `cbgo` and services/ as `cbgo.services`, so the distribution adds
exactly one top-level import name. Subpackages are found automatically, so a new module or
service folder needs no edit here.

Data files: those directly in a package folder by the patterns of pyproject.toml's
``[tool.setuptools.package-data]``; and every file in a package's folders that are not packages
themselves (no ``__init__.py``: ``services/intent/models/``, ``shared/cbgo/demo/sessions/``,
...), whatever its name, so a new data folder needs no edit either. MANIFEST.in puts the same
files in the sdist. tests/packaging/test_wheel.py checks that a wheel carries every file of the
two roots that git tracks.
"""

import os
from pathlib import Path

from setuptools import find_packages, setup

ROOTS = {"cbgo": "shared/cbgo", "cbgo.services": "services"}
SKIP = {"__pycache__"}


def data_folders(package_dir: Path) -> list[Path]:
    """The folders under one package's folder that are not packages (no ``__init__.py``)."""
    found = []
    for child in sorted(package_dir.iterdir()):
        if not child.is_dir() or child.name in SKIP or (child / "__init__.py").exists():
            continue
        found.append(child)
        found += [Path(folder) / d for folder, dirs, _ in os.walk(child)
                  for d in sorted(dirs) if d not in SKIP]
    return found


packages, package_data = [], {}
for name, path in ROOTS.items():
    for package in [name] + [f"{name}.{sub}" for sub in find_packages(path)]:
        packages.append(package)
        folder = Path(path, *package.split(".")[len(name.split(".")):])
        # Each data folder is listed as a (namespace) package of its own, all its files as its
        # data: setuptools warns about, and may one day drop, data in folders that are not.
        for data in data_folders(folder):
            dotted = ".".join([package, *data.relative_to(folder).parts])
            packages.append(dotted)
            package_data[dotted] = [f.name for f in sorted(data.iterdir()) if f.is_file()
                                    and not f.name.endswith((".pyc", ".pyo"))]

setup(packages=packages, package_dir=ROOTS, package_data=package_data)
