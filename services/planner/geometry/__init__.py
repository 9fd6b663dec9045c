"""Planner geometry every stage uses: clearances to obstacles, the NURBS curve and its
arc-length table (the planned path)."""
