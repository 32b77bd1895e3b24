"""Demonstration datasets (robomimic-style HDF5), their stage segmentation, and the one error every loader of a file
a user may hand us raises (:class:`hrc_lab.data.files.DataFileError`)."""
