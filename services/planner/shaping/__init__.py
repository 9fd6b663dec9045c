"""Path shaping: a NURBS fit (eq. 10) refined (eq. 8-9, 19) and checked (eq. 12-13, 20)."""
