"""The loop's validation harness: scenarios with a hidden truth run end to end and judged.

* :mod:`twin.harness.scenarios`: what a scenario hides (library effects, local changes) and how it is written;
* :mod:`twin.harness.demo`: one scenario through the whole loop (``twin demo``: FMU, signals, modes, loop);
* :mod:`twin.harness.sweep`: many scenarios and seeds on Dask workers (``twin sweep``), each judged;
* :mod:`twin.harness.sweep_report`: the sweep's table and summary.

The loop itself (:mod:`twin.loop`) knows nothing of a hidden truth; the harness is how it is measured.
"""
