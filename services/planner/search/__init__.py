"""Search: the cost map (eq. 5-6, 17), moving obstacles predicted, graph search (eq. 15-16)."""
