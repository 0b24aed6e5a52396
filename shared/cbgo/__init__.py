"""cbgo: context-based gesture operation, as Zenoh-distributed microservices.

The shared library every service uses: key expressions (`cbgo.keys`), the wire format
(`cbgo.wire`), configuration (`cbgo.config`) and the service runtime (`cbgo.runtime`).
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("cbgo")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0.0.0+unknown"
