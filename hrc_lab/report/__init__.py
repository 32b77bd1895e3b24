"""Reports: MLflow runs of a table -> markdown + PNG beside the thesis' published values."""
