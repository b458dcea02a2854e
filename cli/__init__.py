"""tactilab.cli."""
