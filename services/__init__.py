"""One sub-package per tidelink process and the tools around them."""

import common  # noqa: F401 - first: it sets the process's BLAS threads before numpy loads
