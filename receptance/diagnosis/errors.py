"""Errors of the diagnosis: the toolkit's own, named, so callers can tell them from bugs."""

from __future__ import annotations

from receptance.modal_model import ModelError

__all__ = ["DiagnosisError", "EffectNotApplicable"]


class DiagnosisError(ModelError):
    """The diagnosis cannot run (names the measurement, model or candidate at fault)."""


class EffectNotApplicable(DiagnosisError):
    """A catalogued effect cannot be applied to this model.

    Attributes
    ----------
    effect : str
        Catalogue name.
    reason : str
        What is missing or inconsistent (names the point, node or value).
    remedy : str
        What would make it apply (a point to add, a description value to state).
    """

    def __init__(self, effect: str, reason: str, remedy: str):
        super().__init__(f"{effect} cannot be applied: {reason} (to apply it: {remedy})")
        self.effect = effect
        self.reason = reason
        self.remedy = remedy

    def to_dict(self) -> dict:
        """The ``not_applicable`` entry of ``diagnosis.json``."""
        return {"name": self.effect, "reason": self.reason, "what_would_make_it_apply": self.remedy}

    def __reduce__(self):  # picklable across the diagnosis' worker processes
        return (type(self), (self.effect, self.reason, self.remedy))
