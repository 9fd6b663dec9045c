"""One sub-package per tidelink process and the tools around them."""
