"""tactilab.experiments."""
