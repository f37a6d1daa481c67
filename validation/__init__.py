"""validation: cases holding each tier against the paper, analytic solutions and the tier below,
speed benchmarks, and the HTML report (``python -m validation report --out DIR``).

Cases live in ``cases_<tier>.py``, benchmarks in ``bench_<tier>.py``; both register through
:mod:`validation.framework` and are discovered automatically.
"""
