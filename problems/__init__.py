"""fdisyn.problems — one module per reference plant."""
