"""The harness: the layer on top of the model (`mechval`, core/), the
engine adapters (`mechval.engines`) and the reports (`mechval.reports`).

It is the only code that knows all three: the command line, running tasks
in worker processes (locally or on Dask), the comparison runs, the
work-precision sweeps and the engine baselines.
"""
