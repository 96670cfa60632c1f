"""Print the OpenBLAS kernel(s) NumPy's and SciPy's OpenBLAS builds picked in this process (e.g. ``SkylakeX``),
one name per build, space-separated; nothing when none can be asked. ``.ci/run`` reruns the solver-dependent
tests under each other kernel, and skips a rerun under the kernel the suite itself just ran on."""

import ctypes
import re

import numpy  # noqa: F401 - loads NumPy's OpenBLAS
import scipy.linalg  # noqa: F401 - loads SciPy's

SYMBOLS = ("scipy_openblas_get_corename64_", "scipy_openblas_get_corename", "openblas_get_corename64_", "openblas_get_corename")

names = []
with open("/proc/self/maps", encoding="utf-8") as maps:
    paths = sorted({line.split()[-1] for line in maps if re.search(r"openblas[^/]*\.so", line)})
for path in paths:
    lib = ctypes.CDLL(path)
    for sym in SYMBOLS:
        fn = getattr(lib, sym, None)
        if fn is not None:
            fn.restype = ctypes.c_char_p
            names.append(fn().decode())
            break
print(" ".join(sorted(set(names))))
