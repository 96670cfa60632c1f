"""The synthesis methods, one module (or subpackage) per method, and the registry that lists them.
"""
