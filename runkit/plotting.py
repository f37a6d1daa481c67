"""matplotlib for files, never a display: the Agg backend set once for every tier's figures.

Every module that draws imports ``plt`` from here (``from runkit.plotting import plt``)."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402,F401
