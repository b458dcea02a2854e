"""tactilab.forward."""
