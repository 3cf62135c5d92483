"""The MPEG-4 face animation standard as data and code: FAP and feature-point tables, FAPU."""

from .fapu import ANGLE_UNIT, Fapu, fapu_from_points, metres_per_unit
from .tables import FAP_COUNT, FapTable, FeaturePointTable, fap_table, feature_points

__all__ = ["ANGLE_UNIT", "FAP_COUNT", "Fapu", "FapTable", "FeaturePointTable", "fap_table",
           "fapu_from_points", "feature_points", "metres_per_unit"]
