"""The application: command line, plant files, the reproduce pipeline, reports, benchmarks.
"""

from pathlib import Path

WORKDIR = Path(".fdisyn")
"""The default work folder of ``reproduce``, ``report``, ``evaluate`` and ``bench`` (``--workdir``): the
designs, generated C and compiled libraries, under ``<problem>/<design>``. A hidden folder of the current
directory, like ``.pytest_cache``: the builds stay with the reports they serve, two projects (or two
clones) never share one, and setuptools' own ``build/`` folder (``pip install .``) is left to it."""
