"""Moving a target mesh the way a source moved: sparse (control points) and dense (clone) transfer."""

from .regions import REGIONS, label_regions, region_mask
from .transfer import METHODS, METRICS, ControlPairs, DenseTransfer, SparseTransfer, transfer_expression

__all__ = ["METHODS", "METRICS", "REGIONS", "ControlPairs", "DenseTransfer", "SparseTransfer", "label_regions",
           "region_mask", "transfer_expression"]
