"""The application: command line, plant files, the reproduce pipeline, reports, benchmarks.
"""
