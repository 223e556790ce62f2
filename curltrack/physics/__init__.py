"""The one model core: closed forms, equations of motion, effect terms."""

from . import closed_form

__all__ = ["closed_form"]
