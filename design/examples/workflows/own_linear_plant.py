"""Your own linear plant, from Python to a report page: two designs compared on one page, a trace plotted,
and the plant written as a TOML plant file that designs the same diagnoser.

Run it in an empty folder (``python own_linear_plant.py [RUNS]``; the suite runs it with few runs). It writes
``motor.toml``, ``motor_trace.png``, ``reports/motor/index.html`` and builds in ``.fdisyn/``; a notebook runs
the same cells, with ``fig`` shown inline instead of saved.
"""

import sys
from pathlib import Path

import control
import numpy as np

import fdisyn

RUNS = int(sys.argv[1]) if len(sys.argv) > 1 else 50

# %% The plant: a DC motor (R = 1 Ω, L = 0.01 H, K = 0.05 N·m/A, J = 1e-3 kg·m², b = 1e-4 N·m·s) whose load
# torque is unknown, sampled at 1 kHz; python-control's signal names are kept, the units are ours.
A = [[-100.0, -5.0, 0.0], [50.0, -0.1, 0.0], [0.0, 1.0, 0.0]]
B = [[100.0, 0.0], [0.0, -1000.0], [0.0, 0.0]]  # columns: voltage (known), load torque (unknown)
sys_c = control.ss(A, B, np.eye(3), 0, states=["current", "speed", "angle"], inputs=["voltage", "load"],
                   outputs=["i_meas", "w_meas", "theta_meas"])
Ts = 0.001
plant = fdisyn.LinearPlant.from_control(
    control.c2d(sys_c, Ts), n_unknown=1,
    Q=np.diag([1e-7, 1e-6, 0.0]),  # covariance per sample (a continuous intensity times Ts)
    R=np.diag([1e-4, 2.5e-3, 1e-6]),
    units={"voltage": "V", "load": "N·m", "i_meas": "A", "w_meas": "rad/s", "theta_meas": "rad"},
    labels={"i_meas": "current", "w_meas": "speed", "theta_meas": "angle"},
)

# %% Two designs side by side, the motor running at switch-on, a speed sensor that reads 1 rad/s high
bank = [["i_meas", "theta_meas"], ["w_meas", "theta_meas"]]
designs = {
    "kalman": {"method": "kalman_uio", "bank": bank},
    "wssr": {"method": "kalman_uio", "bank": bank, "detector": "wssr", "window": 25},
}
simulation = {"duration": 4.0, "x0": [0.4, 0.0, 0.0],
              "inputs": [{"kind": "step", "offset": 0.4, "amplitude": 5.6, "start": 0.5}],
              "unknown_inputs": [{"kind": "gauss_markov", "offset": 0.02, "amplitude": 0.01, "period": 0.5}]}
scenarios = [{"name": "speed_offset", "duration": 4.0, "fault": "w_meas", "onset": 2.0,
              "sensor_faults": [{"sensor": "w_meas", "kind": "offset", "value": 1.0}]}]
problem = fdisyn.problem(plant, name="motor", designs=designs, simulation=simulation, scenarios=scenarios)

# %% The compiled Monte Carlo of both designs, and one page comparing them
evaluation = fdisyn.evaluate(problem, runs=RUNS)
for design, per in evaluation.metrics.items():
    quiet, fault = per["fault_free"], per["speed_offset"]
    print(f"{design}: false alarm in {quiet.false_alarm_runs:.0%} of fault-free runs; speed offset missed in "
          f"{fault.missed_detection_rate:.0%}, found after {fault.detection_delay_median_s} s (median), "
          f"isolated in {fault.isolation_accuracy:.0%}")
page = fdisyn.report(problem, runs=RUNS)
print(f"wrote {page}")

# %% One run plotted: statistics over thresholds, alarms, the isolated fault (shown inline in a notebook)
gf = problem.design("kalman")
trace = fdisyn.simulate(problem, "speed_offset", seed=1)
fig = fdisyn.plot_trace(gf, trace, labels=problem.labels, signals=["w_meas"])
fig.savefig("motor_trace.png")

# %% The plant as a plant file: `fdisyn design motor.toml --design kalman --out DIR` designs the same diagnoser
Path("motor.toml").write_text(plant.to_toml("motor", designs=designs, simulation=simulation, scenarios=scenarios), encoding="utf-8")
again = fdisyn.problem(plant, name="motor", designs=designs).design("kalman")
print("the plant file designs the same generators:",
      all(np.array_equal(a.Ar, b.Ar) and np.array_equal(a.By, b.By) for a, b in zip(gf.generators, again.generators)))
