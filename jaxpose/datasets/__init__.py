"""Datasets: the procedural 12-class deformation dataset and a folder-of-classes loader."""
from jaxpose.datasets.folder import load_folder
from jaxpose.datasets.procedural import CLASSES, DEFORMATIONS, make_dataset, make_object

__all__ = ["CLASSES", "DEFORMATIONS", "make_object", "make_dataset", "load_folder"]
