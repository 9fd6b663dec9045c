"""Planner geometry every stage uses: clearances to obstacles and the NURBS curve."""
