"""The live demo: ``python serve.py [options]`` (same as ``python -m tileviz serve``).

Starts the simulation, vision and the interval localizer and serves them in the browser on
http://127.0.0.1:8080 by default; ``python serve.py --help`` lists the options. Ctrl-C stops it.
"""

import sys

from tileviz.cliutil import missing_dependency

if __name__ == "__main__":
    missing = missing_dependency("serve.py")
    if missing is not None:
        sys.stderr.write(missing + "\n")
        raise SystemExit(2)
    from tileviz.app.serve_cli import main

    raise SystemExit(main("serve", sys.argv[1:]))
