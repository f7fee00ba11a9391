"""Root pytest configuration shared by the unit tests and nbval."""

import os

# An inherited backend (e.g. MPLBACKEND=Agg in CI) would stop the kernels nbval starts from producing
# inline figures, and the stored "<Figure ...>" outputs would then not match.
os.environ.pop("MPLBACKEND", None)
