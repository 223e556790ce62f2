"""The one model core: closed forms, equations of motion, effect terms."""

from . import closed_form
from .dynamics import simulate
from .effects import EFFECTS, Effect, EffectDef, register
from .shot import ShotModel, Trajectory

__all__ = ["closed_form", "simulate", "Effect", "EffectDef", "EFFECTS", "register", "ShotModel",
           "Trajectory"]
