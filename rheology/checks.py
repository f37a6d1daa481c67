"""The input checks of :mod:`runkit.params` and :mod:`runkit.limits` under their former names."""

from runkit.limits import available_memory, check_memory  # noqa: F401
from runkit.params import check_nonnegative, check_positive, check_range, valid_interval  # noqa: F401
