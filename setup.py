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


def data_folder_files(package_dir: Path) -> list[str]:
    """Files under the non-package folders of one package, relative to the package folder."""
    found = []
    for child in sorted(package_dir.iterdir()):
        if not child.is_dir() or child.name in SKIP or (child / "__init__.py").exists():
            continue
        for folder, dirs, files in os.walk(child):
            dirs[:] = sorted(d for d in dirs if d not in SKIP)
            found += [str((Path(folder) / f).relative_to(package_dir)) for f in sorted(files)
                      if not f.endswith((".pyc", ".pyo"))]
    return found


packages, package_data = [], {}
for name, path in ROOTS.items():
    for package in [name] + [f"{name}.{sub}" for sub in find_packages(path)]:
        packages.append(package)
        folder = Path(path, *package.split(".")[len(name.split(".")):])
        files = data_folder_files(folder)
        if files:
            package_data[package] = files

setup(packages=packages, package_dir=ROOTS, package_data=package_data)
