"""tactilab.data_schemas."""
