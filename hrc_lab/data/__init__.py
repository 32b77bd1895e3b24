"""Demonstration datasets (robomimic-style HDF5) and their stage segmentation."""
