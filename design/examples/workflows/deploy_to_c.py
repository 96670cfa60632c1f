"""Deploy a diagnoser into a firmware: design it, export its C, build a program with its own ``main`` against the
files ``DIR/c/SOURCES`` lists under ``-Wall -Wextra -Werror -pedantic``, run a trace through it and compare it
with the Python reference; then the same in single precision.

Run it in an empty folder (``python deploy_to_c.py``; needs a C compiler, ``$CC`` or ``cc``). It writes the
export ``tanks/`` and the program ``firmware``.
"""

import os
import shlex
import subprocess
from pathlib import Path

import numpy as np

import fdisyn

# %% A plant of your own: two tanks in cascade, both levels measured (m), the pump's command known
TS = 1.0
plant = fdisyn.LinearPlant(
    [[0.95, 0.0], [0.05, 0.96]], [[0.02], [0.0]], np.eye(2), 0.0, TS,  # A, B, C, D, Ts, as control.ss takes them
    Q=np.diag([1e-6, 1e-6]), R=np.diag([1e-4, 1e-4]), inputs=["pump"], outputs=["h1", "h2"],
    units={"h1": "m", "h2": "m", "pump": "1"}, labels={"h1": "level of tank 1", "h2": "level of tank 2"},
)
gf = fdisyn.design(plant, "kalman_uio", name="tanks")
fdisyn.export(gf, "tanks")

# %% The firmware: its own main, a static state, one step per sample read from stdin ("u h1 h2" per line)
Path("main.c").write_text("""#include <stdio.h>
#include "tanks.h"

static double state[TANKS_NSTATE];

int main(void) {
    double u[TANKS_NU], y[TANKS_NY], r[TANKS_NR], J[TANKS_NJ];
    int alarm, isolated;
    tanks_init(state);
    while (scanf("%lf %lf %lf", &u[0], &y[0], &y[1]) == 3) {
        tanks_step(state, u, y, r, J, &alarm, &isolated);
        printf("%.17g %.17g %d %d\\n", r[0], J[0], alarm, isolated);
    }
    return 0;
}
""", encoding="utf-8")
sources = [f"tanks/c/{s}" for s in Path("tanks/c/SOURCES").read_text(encoding="utf-8").split()]
cc = shlex.split(os.environ.get("CC", "cc"))
flags = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-pedantic", "-Itanks/c"]
subprocess.run([*cc, *flags, "main.c", *sources, "-o", "firmware", "-lm"], check=True)

# %% A run of the plant with h2's sensor reading 10 cm high from t = 600 s, through the firmware and through Python
rng = np.random.default_rng(1)
T = 1200
U = np.where((np.arange(T) // 300) % 2 == 0, 1.0, -1.0)[:, None]
x = np.linalg.solve(np.eye(2) - plant.A, plant.B[:, 0])  # running at switch-on
Y = np.empty((T, 2))
for k in range(T):
    Y[k] = plant.C @ x + rng.normal(0.0, 1e-2, 2) + (k >= 600) * np.array([0.0, 0.10])
    x = plant.A @ x + plant.B @ U[k] + rng.normal(0.0, 1e-3, 2)
lines = "".join(f"{float(u[0])!r} {float(y[0])!r} {float(y[1])!r}\n" for u, y in zip(U, Y))
out = subprocess.run(["./firmware"], input=lines, capture_output=True, text=True, check=True).stdout
fw = np.array([[float(v) for v in line.split()] for line in out.splitlines()])
ref = fdisyn.load("tanks", backend="reference").run(U, Y)
error = np.max(np.abs(fw[:, 0] - ref.r[:, 0])) / max(1.0, np.max(np.abs(ref.r[:, 0])))
same = np.array_equal(fw[:, 2].astype(int), ref.alarm.reshape(T, -1).any(axis=1).astype(int))
print(f"the firmware's residuals agree with the Python reference: max error {error:.1e}, alarms identical: {same}")
first = int(np.argmax(fw[:, 2] > 0))
print(f"first alarm at t = {first * TS:.0f} s, isolated fault: {gf.faults[int(fw[first:, 3].max())]}")
assert error < 1e-9 and same  # the generated C is the reference's arithmetic to round-off

# %% Single precision, for a target without a double-precision FPU: the same API, float arithmetic inside
fdisyn.export(gf, "tanks", precision="single")  # as `fdisyn codegen tanks --precision single`
subprocess.run([*cc, *flags, "main.c", *sources, "-o", "firmware_f", "-lm"], check=True)
out = subprocess.run(["./firmware_f"], input=lines, capture_output=True, text=True, check=True).stdout
ff = np.array([[float(v) for v in line.split()] for line in out.splitlines()])
print(f"single precision: residuals within {np.max(np.abs(ff[:, 0] - fw[:, 0])):.1e} m of the double build, "
      f"alarms identical: {np.array_equal(ff[:, 2], fw[:, 2])}")
