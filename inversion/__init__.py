"""tactilab.inversion."""
