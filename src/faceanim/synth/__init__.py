"""Expressions made, not captured: Waters vector muscles, FACS action units, emotions, and the
reverse, action-unit intensities read from motion."""

from .expression import au_fields, expression_field, synthesise
from .face import MuscleFace
from .facs import ACTION_UNITS, parse_recipe, recipe_text

__all__ = ["MuscleFace", "ACTION_UNITS", "parse_recipe", "recipe_text", "expression_field", "synthesise",
           "au_fields"]
