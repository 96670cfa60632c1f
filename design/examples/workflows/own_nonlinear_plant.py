"""Your own nonlinear plant: a model by expressions, the nonlinear adaptive fault detection filter (Zhou, Xi &
Zhang, Shanghai Jiao Tong University, c. 1991) evaluated and reported on its page, a run plotted with the
parameter estimates against the truth, and the plant written as a plant file.

Run it in an empty folder (``python own_nonlinear_plant.py [RUNS]``). It writes ``ship.toml``,
``ship_trace.png`` and ``reports/ship/index.html``.
"""

import sys
from pathlib import Path

import fdisyn

RUNS = int(sys.argv[1]) if len(sys.argv) > 1 else 50

# %% The plant: x(k+1) = 0.1·a·x² + x + 0.1·b·u + v, y = x + e (Zhou, Xi & Zhang, eq. (3.1)), time in samples
plant = fdisyn.NonlinearPlant.from_expressions(
    states=["x"], inputs=["u"], outputs=["y"], parameters=["a", "b"], nominal={"a": -0.58, "b": 0.2},
    f={"x": "0.1*a*x^2 + x + 0.1*b*u"}, h={"y": "x"}, Q=[[0.0]], R=[[0.01]],
    units={"y": "m/s", "u": "1"}, labels={"y": "shaft speed", "u": "throttle", "a": "hull resistance", "b": "propeller thrust"},
)

# %% The NAFDF at the paper's budget (P_f per sample), the plant running from rest, its parameter a halved at 701
nafdf = {"method": "nafdf", "window": 10, "P0": 100.0, "theta0": {"a": 0.0, "b": 0.0}, "R0": [[100.0, 5.0], [5.0, 10.0]],
         "forgetting_final": 0.99, "theta_lower": {"a": -10.0, "b": 0.0}, "theta_upper": {"a": 0.0, "b": 10.0},
         "nominal_samples": 300, "classifier_window": 50, "W1": 50.0, "W2": 350.0, "T1": 50,
         "isolable_jump": {"a": 0.29, "b": 0.1}}
designs = {"nafdf": {**nafdf, "P_f": 1e-4}}
simulation = {"duration": 4000, "x0": [0.0], "inputs": [{"kind": "square", "offset": 5.0, "amplitude": 4.0, "period": 50}]}
scenarios = [{"name": "a_half", "duration": 2000, "onset": 701, "parameter_faults": [{"parameter": "a", "scale": 0.5}]}]
problem = fdisyn.problem(plant, name="ship", designs=designs, simulation=simulation, scenarios=scenarios)

# %% The compiled Monte Carlo (the operating characteristic on copies of the diagnoser with scaled thresholds)
page = fdisyn.report(problem, runs=RUNS)
print(f"wrote {page}")

# %% One run: the statistics, the isolated parameter, the estimates of a and b against the truth
gf = problem.design("nafdf")
trace = fdisyn.simulate(problem, "a_half", seed=2)
monitor = fdisyn.load(fdisyn.export(gf, "ship_nafdf"))  # the compiled step (the NAFDF's step exists only as C)
fig = fdisyn.plot_trace(gf, trace, monitor.run(trace.U, trace.Y), labels=problem.labels, signals=["y"])
fig.savefig("ship_trace.png")

# %% The plant file of this problem
Path("ship.toml").write_text(plant.to_toml("ship", designs=designs, simulation=simulation, scenarios=scenarios), encoding="utf-8")
