"""Remote monitoring in the Foxglove app: the view of a run (view.py) and its live bridge."""
