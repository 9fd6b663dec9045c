"""`tidelink monitor`: watch live runs from any machine (state, loop, views)."""
