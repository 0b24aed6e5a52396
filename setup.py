"""Package discovery for the two source roots (metadata lives in pyproject.toml).

shared/cbgo/ installs as `cbgo` and services/ as `cbgo.services`, so the distribution adds
exactly one top-level import name. Subpackages are found automatically, so a new module or
service folder needs no edit here.
"""

from setuptools import find_packages, setup

ROOTS = {"cbgo": "shared/cbgo", "cbgo.services": "services"}

packages = []
for name, path in ROOTS.items():
    packages += [name] + [f"{name}.{sub}" for sub in find_packages(path)]

setup(packages=packages, package_dir=ROOTS)
