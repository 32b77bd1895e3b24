"""VMRD v2's on-disk layout, checked without reading an annotation (:mod:`hrc_lab.data.vmrd` reads and writes the
data sets; ``env.vmrd_root``'s validation, :class:`hrc_lab.env.clutter.spec.VmrdSpec`, checks a root with
:func:`check_layout` before any work). Imports nothing of hrc_lab's simulators, so the env config can use it."""

from __future__ import annotations

from pathlib import Path

from hrc_lab.data.files import DataFileError

SPLITS = ("trainval", "test")


def check_layout(root: str | Path) -> Path:
    """``root`` as a :class:`Path` once its folders and image sets are there (fast: reads no annotation)."""
    root = Path(root)
    if not root.is_dir():
        raise DataFileError(f"{root}: no such directory (a data set in VMRD's layout: Annotations/, JPEGImages/, "
                            "ImageSets/Main/trainval.txt and test.txt)")
    for folder in ("Annotations", "JPEGImages"):
        if not (root / folder).is_dir():
            raise DataFileError(f"{root}: has no {folder}/ folder; not a data set in VMRD's layout")
    for split in SPLITS:
        existing = root / "ImageSets" / "Main" / f"{split}.txt"
        if not existing.is_file():
            raise DataFileError(f"{existing}: missing; a VMRD-layout data set lists its {split} images there")
    return root
