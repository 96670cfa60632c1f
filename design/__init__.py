"""fdisyn.design — everything offline: plants, synthesis, verification, export, evaluation."""
