"""``make docs``: regenerate every generated part of the docs.

``--check`` changes nothing and says which are out of step (exit 1).
"""

import argparse
import sys

from cbgo_tools.docs import REPO, stale_layout, stale_schemas
from cbgo_tools.docs.protocol_examples import stale_protocol
from cbgo_tools.docs.readme_tables import stale_readmes


def main() -> int:
    """Regenerates (or checks) the README tables, protocol examples, schemas and layout."""
    parser = argparse.ArgumentParser(prog="make docs", description=__doc__)
    parser.add_argument("--check", action="store_true", help="change nothing; exit 1 if stale")
    args = parser.parse_args()
    stale = [path for step in (stale_readmes, stale_protocol, stale_schemas, stale_layout)
             for path in step(write=not args.check)]
    verb = "out of step" if args.check else "rewritten"
    names = ", ".join(str(p.relative_to(REPO)) for p in stale)
    print(f"{len(stale)} generated file(s) {verb}" + (f": {names}" if stale else ""))
    return 1 if args.check and stale else 0


sys.exit(main())
