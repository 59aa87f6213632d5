"""The wheelset's modal model: FE shapes with chosen frequencies and damping, plus structural modifications.

Thesis §2.3: the receptance between any two DOFs follows from the mode
shapes, natural frequencies and damping ratios (eqs. 2.23–2.30).  The hybrid
model of the thesis takes the shapes from FE and the frequencies and damping
from the test (see :mod:`receptance.hybrid`).  Physical effects the FE lacks
(primary suspension, rig springs, bearings...) enter as structural
modifications (:mod:`receptance.modification`) solved in modal coordinates.

Solving.  The model is reduced once to poles and residues
(:class:`~receptance.pole_residue.PoleResidues`): modal coordinates that no
modification touches keep their closed-form modal terms; the touched ones
(and added bodies) form a small system whose unrestrained rigid-body part
gives a mass line and whose remainder is diagonalised in first-order
(state-space) form.  Receptances at any set of frequencies are then one
vectorised evaluation.

Effects present during the test (rig springs, sensor masses, bearings,
press fits) are already in the measured frequencies.  The modified system
is then solved from the design model — FE frequencies plus the effect: the
physics — and every pole that carries a measured mode (a paired FE mode,
or a mode the effect creates near a measured mode without FE partner) is
given the test's frequency and damping, as the hybrid model does for
unmodified modes.  ``max_hz`` keeps the model to the test band while FE
modes above it remain the basis of the modifications.
"""

from __future__ import annotations

import functools
import logging
import weakref
from dataclasses import dataclass, field, replace
from typing import Mapping, Sequence

import numpy as np
import pandas as pd
import scipy.linalg
import scipy.optimize

from ema.frf import QUANTITIES, FrequencyResponse
from fem_import.modes import FEModes
from receptance.dofs import Dof, DofError, Point, dofs_from_channels, parse_dof
from receptance.modification import Modification, RigidBody
from receptance.pole_residue import PoleResidues

__all__ = ["ModalModel", "ModelError", "ORIGINS", "ChannelTerms"]

log = logging.getLogger("receptance")

#: where a mode's frequency and damping come from
ORIGINS = ("test", "fe", "rigid")
_BODY_AXES = {"x": 0, "y": 1, "z": 2, "rx": 3, "ry": 4, "rz": 5}
_DECOUPLED = 1e-9  # coupling below this fraction of a coordinate's own scale leaves it a plain modal term
#: a mode an effect creates takes a measured-only mode's frequency and damping within this relative distance
TEST_ONLY_RTOL = 0.03
#: FE rows of DOFs, per FE export (weakly held): a fit evaluates hundreds of models on one export
_ROW_CACHE: "weakref.WeakKeyDictionary[FEModes, dict]" = weakref.WeakKeyDictionary()
_ROW_CACHE_SIZE = 20000


class ModelError(ValueError):
    """An inconsistent modal model (names the mode, DOF or parameter)."""


@dataclass(frozen=True)
class ChannelTerms:
    """Terms that exist only at measured channels: residuals and measured-only modes (curve-fit terms).

    For channel ``c`` of setup ``setup`` the model's receptance gains
    ``lower[c] / s² + upper[c] + Σ_r A_r[c] / (s² + 2ζ_r ω_r s + ω_r²)``:
    a lower residual (mass line of modes below the band), an upper residual
    (flexibility of modes above it) and modes seen in the test but absent from
    the FE (modal constants ``A_r`` from the test's force point).  They have
    no shape away from the channels, so they act on :meth:`ModalModel.frf_at_channels` only.

    Parameters
    ----------
    kind : str
        The effect that made them (``"residuals"``, ``"experimental_mode"``).
    setup : str
        Setup whose channels they belong to ("" for every setup).
    lower, upper : dict of str -> complex
        Per channel name [m/N · (rad/s)²] and [m/N].
    modes : tuple of (f_hz, zeta, dict of str -> complex)
    """

    kind: str
    setup: str = ""
    lower: Mapping[str, complex] = field(default_factory=dict)
    upper: Mapping[str, complex] = field(default_factory=dict)
    modes: tuple = ()

    def receptance(self, names: Sequence[str], s: np.ndarray) -> np.ndarray:
        """(n_channels, n_freq) receptance of these terms at the Laplace variable ``s``."""
        out = np.zeros((len(names), s.size), complex)
        for i, name in enumerate(names):
            if name in self.lower:
                out[i] += self.lower[name] / s**2
            if name in self.upper:
                out[i] += self.upper[name]
            for f, z, res in self.modes:
                if name in res:
                    w = 2 * np.pi * f
                    out[i] += res[name] / (s**2 + 2 * z * w * s + w**2)
        return out


@dataclass(frozen=True, eq=False)
class ModalModel:
    """Modal model of the wheelset.

    Parameters
    ----------
    fe : FEModes
        Mass-normalised shapes of the kept modes (one FE mode per model mode,
        same order); ``fe.freqs_hz`` keeps the FE frequencies for reference.
    freqs_hz : ndarray (m,)
        Natural frequencies used by the model [Hz] (0 for rigid-body modes).
    zeta : ndarray (m,)
        Viscous modal damping ratios.
    origin : tuple of str
        ``"test"`` (frequency and damping from the test), ``"fe"`` (FE
        frequency, default damping) or ``"rigid"``.
    fe_mode : ndarray of int (m,)
        1-based number of each mode in the FE export it came from.
    test_mode : ndarray of float (m,)
        1-based test mode each mode was paired with (NaN if none).
    points : dict of str -> Point
        Named points (contact points, axleboxes, sensors...).
    modifications : tuple of Modification
        Applied in order; see :meth:`with_modification`.
    name : str
    history : tuple of str
    channel_terms : tuple of ChannelTerms
        Residual / measured-only-mode terms at measured channels.
    max_hz : float or None
        Modes of the (modified) model above this frequency are left out of
        its receptances: the model holds the modes of the test band (thesis
        Table 3.1) and out-of-band modes are the residuals' business.  FE
        modes above it still serve as the basis in which structural
        modifications are solved — a local modification (a bearing, a joint)
        needs them.  None keeps every mode.
    test_only : tuple of (float, float)
        Measured modes without an FE partner, ``(f_hz, zeta)``.  An effect
        that creates a mode the FE lacks (the axlebox rocking on its bearing)
        gives that mode the measured frequency and damping when one lies
        close (see :meth:`_pin`), as the hybrid model does for paired modes.
    """

    fe: FEModes
    freqs_hz: np.ndarray
    zeta: np.ndarray
    origin: tuple[str, ...]
    fe_mode: np.ndarray
    test_mode: np.ndarray
    points: Mapping[str, Point] = field(default_factory=dict)
    modifications: tuple[Modification, ...] = ()
    name: str = "hybrid model"
    history: tuple[str, ...] = ()
    channel_terms: tuple[ChannelTerms, ...] = ()
    max_hz: float | None = None
    test_only: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        m = len(self.fe)
        f = np.asarray(self.freqs_hz, float)
        z = np.asarray(self.zeta, float)
        for label, arr in (("freqs_hz", f), ("zeta", z), ("fe_mode", self.fe_mode), ("test_mode", self.test_mode)):
            if np.shape(arr) != (m,):
                raise ModelError(f"{label} must have one entry per FE mode ({m}), got shape {np.shape(arr)}")
        if len(self.origin) != m:
            raise ModelError(f"origin must have {m} entries, got {len(self.origin)}")
        bad = [o for o in self.origin if o not in ORIGINS]
        if bad:
            raise ModelError(f"origin entries must be one of {ORIGINS}, got {sorted(set(bad))}")
        if np.any(~np.isfinite(f)) or np.any(f < 0):
            k = int(np.argmax(~np.isfinite(f) | (f < 0)))
            raise ModelError(f"mode {k + 1}: frequency must be finite and >= 0 Hz, got {f[k]!r}")
        if np.any(~np.isfinite(z)) or np.any((z < 0) | (z >= 1)):
            k = int(np.argmax(~np.isfinite(z) | (z < 0) | (z >= 1)))
            raise ModelError(f"mode {k + 1}: damping ratio must lie in [0, 1), got {z[k]!r}")
        if not self.fe.has_rotations:
            log.info("%s: FE shapes without rotations; off-node points and rotational DOFs are unavailable",
                     self.fe.source or "model")
        elif self.fe.rotation_free.any():
            log.info("%s: %d of %d FE nodes carry no rotations (zero in every mode: solid elements' nodes); a point "
                     "takes such a node's translation only within the tolerance of it", self.fe.source or "model",
                     int(self.fe.rotation_free.sum()), self.fe.rotation_free.size)
        if self.max_hz is not None and not (np.isfinite(self.max_hz) and self.max_hz > 0):
            raise ModelError(f"max_hz must be a positive frequency in Hz or None, got {self.max_hz!r}")
        for mod in self.modifications:
            if not isinstance(mod, Modification):
                raise ModelError(f"modifications must be Modification instances, got {type(mod).__name__}")
        object.__setattr__(self, "freqs_hz", f)
        object.__setattr__(self, "zeta", z)
        object.__setattr__(self, "origin", tuple(self.origin))
        object.__setattr__(self, "fe_mode", np.asarray(self.fe_mode, int))
        object.__setattr__(self, "test_mode", np.asarray(self.test_mode, float))
        object.__setattr__(self, "points", dict(self.points))
        object.__setattr__(self, "modifications", tuple(self.modifications))
        object.__setattr__(self, "history", tuple(self.history))
        object.__setattr__(self, "channel_terms", tuple(self.channel_terms))
        object.__setattr__(self, "test_only", tuple((float(f), float(z)) for f, z in self.test_only))

    # ------------------------------------------------------------------ views
    def __len__(self) -> int:
        return self.freqs_hz.size

    @property
    def table(self) -> pd.DataFrame:
        """One row per mode: ``fe_mode, f_fe_hz, f_hz, zeta, origin, test_mode``."""
        return pd.DataFrame({"fe_mode": self.fe_mode, "f_fe_hz": self.fe.freqs_hz, "f_hz": self.freqs_hz,
                             "zeta": self.zeta, "origin": list(self.origin), "test_mode": self.test_mode})

    @functools.cached_property
    def bodies(self) -> tuple[RigidBody, ...]:
        out: list[RigidBody] = []
        for mod in self.modifications:
            out.extend(mod.bodies())
        names = [b.name for b in out]
        if len(set(names)) != len(names):
            raise ModelError(f"added bodies must have unique names, got {names}")
        return tuple(out)

    @property
    def n_coordinates(self) -> int:
        """Modal coordinates plus 6 per added rigid body."""
        return len(self) + 6 * len(self.bodies)

    # ----------------------------------------------------------- new models
    def with_modification(self, modification: Modification) -> "ModalModel":
        """A new model with ``modification`` added (the physical effect is solved in modal coordinates)."""
        if not isinstance(modification, Modification):
            raise ModelError(f"expected a Modification, got {type(modification).__name__}")
        return replace(self, modifications=self.modifications + (modification,),
                       history=self.history + (f"+ {modification.describe()}",))

    def with_effect(self, effect, values: Mapping[str, float] | None = None, setups: Sequence = ()
                    ) -> "ModalModel":
        """A new model with a catalogued physical effect added (:mod:`receptance.diagnosis.effects`).

        Parameters
        ----------
        effect : Effect or EffectFit
            An effect with its parameter ``values``, or a fit from
            :func:`receptance.diagnosis.fit_effect` / ``diagnose`` (its fitted
            values and its attachment — where it sat, what it assumed — are
            used).
        values : dict, optional
            Parameter values by name (see ``effect.parameters()``).
        setups : sequence of DataFrame, optional
            The tests' channel tables (effects at the sensors need them).
        """
        if values is None and hasattr(effect, "effect") and hasattr(effect, "params"):
            if getattr(effect, "attachment", None) is not None:
                # where the fit attached it (and with the description it used)
                return effect.attachment.apply(self, effect.params)
            effect, values = effect.effect, effect.params
        if not hasattr(effect, "apply"):
            raise ModelError(f"expected a catalogued effect (receptance.diagnosis.effects), got {type(effect).__name__}")
        return effect.apply(self, dict(values or {}), setups)

    def as_designed(self) -> "ModalModel":
        """The physics alone: test-paired modes back at their FE frequencies, no measured-only modes.

        Nothing is pinned to the test any more (the origins say ``"fe"``), so a
        modification moves every mode as the design model plus the effect
        would; damping ratios stay those of the test.
        """
        test = np.array([o == "test" for o in self.origin])
        return replace(self, freqs_hz=np.where(test, self.fe.freqs_hz, self.freqs_hz), test_only=(),
                       origin=tuple("fe" if t else o for o, t in zip(self.origin, test)),
                       history=self.history + ("test frequencies replaced by the FE's (physics alone)",))

    def without_modifications(self) -> "ModalModel":
        """The bare modal model (free-free hybrid model): no modifications, no channel terms."""
        return replace(self, modifications=(), channel_terms=(), history=self.history + ("modifications removed",))

    def with_channel_terms(self, terms: ChannelTerms, *, step: str | None = None) -> "ModalModel":
        """A new model with residual / measured-only-mode terms at measured channels."""
        if not isinstance(terms, ChannelTerms):
            raise ModelError(f"expected ChannelTerms, got {type(terms).__name__}")
        return replace(self, channel_terms=self.channel_terms + (terms,),
                       history=self.history + (step or f"+ {terms.kind} terms ({terms.setup or 'all setups'})",))

    def with_modal_parameters(self, freqs_hz=None, zeta=None, *, step: str = "modal parameters changed"
                              ) -> "ModalModel":
        """A new model with other frequencies and/or damping ratios (same shapes and modifications)."""
        f = self.freqs_hz if freqs_hz is None else np.asarray(freqs_hz, float)
        z = self.zeta if zeta is None else np.asarray(zeta, float)
        return replace(self, freqs_hz=f, zeta=z, history=self.history + (step,))

    def with_points(self, points: Mapping[str, Point] | Sequence[Point]) -> "ModalModel":
        """A new model knowing more named points (added to, or replacing, those it has)."""
        pts = dict(self.points)
        items = points.values() if isinstance(points, Mapping) else points
        for p in items:
            pts[p.name] = p
        return replace(self, points=pts)

    # ------------------------------------------------------------------ rows
    def dof(self, spec) -> Dof:
        """Resolve one DOF specification (see :func:`receptance.dofs.parse_dof`)."""
        if isinstance(spec, str) and ":" in spec:
            body = self._body(spec.split(":", 1)[0])
            if body is not None:
                return parse_dof(spec, {body.name: Point(body.name, None, body.centre)})
        return parse_dof(spec, self.points)

    def rows(self, specs) -> np.ndarray:
        """Rows ``(n, n_coordinates)`` mapping the model's coordinates to the physical DOFs ``specs``.

        For a point attached to FE node ``n`` with offset ``r`` the row is
        ``d · (u_n + θ_n × r)`` per mode (a rigid link, as sensors are
        mounted); for a rotational DOF ``d · θ_n``.  Points attached to a node
        that an added rigid body carries move with that body.
        """
        if isinstance(specs, (str, Dof, int, np.integer)):
            specs = [specs]
        dofs = [self.dof(s) for s in specs]
        return self._rows_of(dofs)

    def _body(self, name: str) -> RigidBody | None:
        for b in self.bodies:
            if b.name == name:
                return b
        return None

    def _rows_of(self, dofs: Sequence[Dof]) -> np.ndarray:
        bodies = self.bodies
        m = len(self)
        T = np.zeros((len(dofs), m + 6 * len(bodies)))
        carried = {int(n): k for k, b in enumerate(bodies) for n in b.carries}
        by_name = {b.name: k for k, b in enumerate(bodies)}
        by_name.update({name: k for k, b in enumerate(bodies) for name in b.carried_points if name not in by_name})
        direct: list[tuple[int, Dof]] = []
        floating: list[tuple[int, Dof, Dof]] = []
        for i, dof in enumerate(dofs):
            d = np.asarray(dof.direction)
            k_body = by_name.get(dof.point.name)
            if k_body is None and dof.point.fe_node is not None and dof.point.fe_node in carried:
                k_body = carried[dof.point.fe_node]
            if k_body is None:
                direct.append((i, dof))
                continue
            b = bodies[k_body]
            p = self._position(dof.point)
            r = p - np.asarray(b.centre)
            row = np.concatenate([np.zeros(3), d]) if dof.rotation else np.concatenate([d, np.cross(r, d)])
            T[i, m + 6 * k_body: m + 6 * k_body + 6] = row
            if b.reference_node is not None and dof.point.name != b.name:
                # floating frame: the part's own deformation relative to its reference node's rigid motion
                ref = Point(f"{b.name}@ref", b.reference_node, tuple(p))
                floating.append((i, dof, Dof(dof.label, ref, dof.direction, dof.rotation)))
        rows = self._fe_rows([d for _, d in direct] + [d for _, d, _ in floating] + [r for _, _, r in floating])
        for k, (i, _) in enumerate(direct):
            T[i, :m] = rows[k]
        nf = len(floating)
        for k, (i, _, _) in enumerate(floating):
            T[i, :m] = rows[len(direct) + k] - rows[len(direct) + nf + k]
        return T

    def _position(self, point: Point) -> np.ndarray:
        if point.xyz is not None:
            return np.asarray(point.xyz, float)
        return self.fe.xyz[self.fe.index(point.fe_node)]

    def _fe_rows(self, dofs: Sequence[Dof]) -> np.ndarray:
        """FE-mode rows ``(len(dofs), modes)`` of DOFs on the FE (rigid links to their nodes), cached per FE.

        The rows depend on the FE modes and the DOF only, not on frequencies or
        modifications, so every model built on the same export (a fit evaluates
        hundreds) shares them.
        """
        cache = _ROW_CACHE.setdefault(self.fe, {})
        out = np.zeros((len(dofs), len(self)))
        todo = []
        for k, dof in enumerate(dofs):
            row = cache.get(dof)
            if row is None:
                todo.append(k)
            else:
                out[k] = row
        trans = [k for k in todo if not dofs[k].rotation]
        for k in todo:
            dof = dofs[k]
            if not dof.rotation:
                continue
            pt = dof.point
            if not self.fe.has_rotations:
                raise DofError(f"DOF {dof.label!r}: the FE shapes have no rotations ({self.fe.source})")
            node = pt.fe_node if pt.fe_node is not None else self.fe.nearest_node(pt.xyz, name=pt.name)
            if self.fe.rotation_free[self.fe.index(node)]:
                raise DofError(f"DOF {dof.label!r}: node {node} carries no rotations (they are zero in every mode "
                               f"of {self.fe.source}: a solid element's node, exported with 6 DOF)")
            out[k] = self.fe.shapes[:, self.fe.index(node), 3:] @ np.asarray(dof.direction)
        if trans:
            pts = [dofs[k].point for k in trans]
            if all(p.xyz is None for p in pts) or all(p.xyz is not None for p in pts):
                pos = None if pts[0].xyz is None else [p.xyz for p in pts]
                out[trans] = self.fe.at_points([p.fe_node for p in pts], pos, [dofs[k].direction for k in trans],
                                               names=[dofs[k].label for k in trans])
            else:
                for k in trans:
                    pt = dofs[k].point
                    pos = None if pt.xyz is None else [pt.xyz]
                    out[k] = self.fe.at_points([pt.fe_node], pos, [dofs[k].direction], names=[dofs[k].label])[0]
        for k in todo:
            if len(cache) < _ROW_CACHE_SIZE:
                cache[dofs[k]] = out[k].copy()
        return out

    # ---------------------------------------------------------------- solving
    def system(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Mass, damping and stiffness matrices in the model's coordinates (eq. 2.29 plus modifications)."""
        return self._system(self.freqs_hz)

    @property
    def base_freqs_hz(self) -> np.ndarray:
        """Frequencies the modified system is solved with.

        When :attr:`pins_test_modes` holds, test-origin modes enter with their
        FE frequencies: the test's frequencies already contain the effects
        being added, so the coupled solve starts from the design model (FE +
        effect: the physics) and the poles that carry a test mode are moved
        back to the test's values afterwards (:meth:`_pin`).  A model that mixes
        such effects with in-service modifications is solved from corrected
        FE frequencies (:meth:`_corrected_base`); any other model from its own
        frequencies.
        """
        if not self.pins_test_modes:
            mixed = any(getattr(mod, "in_test", False) for mod in self.modifications)
            if mixed and any(o == "test" for o in self.origin):
                return self._corrected_base()
            return self.freqs_hz
        base = self.freqs_hz.copy()
        f_fe = self.fe.freqs_hz
        test = np.flatnonzero([o == "test" for o in self.origin])
        # a degenerate FE pair the test split (two planes, two frequencies) keeps the test's relative split,
        # so that the coupled modes stay aligned with the pair's rotated members instead of arbitrary mixtures
        for j in test:
            cluster = test[np.abs(f_fe[test] - f_fe[j]) <= 1e-6 * f_fe[j]]
            base[j] = f_fe[j] * self.freqs_hz[j] / self.freqs_hz[cluster].mean()
        return base

    def _system(self, freqs_hz: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        m = len(self)
        n = self.n_coordinates
        w = 2 * np.pi * np.asarray(freqs_hz, float)
        M = np.zeros((n, n))
        C = np.zeros((n, n))
        K = np.zeros((n, n), complex)
        M[:m, :m] = np.eye(m)
        C[:m, :m] = np.diag(2 * self.zeta * w)
        K[:m, :m] = np.diag(w**2)
        for k, b in enumerate(self.bodies):
            M[m + 6 * k: m + 6 * k + 6, m + 6 * k: m + 6 * k + 6] = b.mass_matrix()
        for mod in self.modifications:
            for t in mod.terms(self.rows):
                T = np.asarray(t.rows, float)
                if T.ndim != 2 or T.shape[1] != n:
                    raise ModelError(f"{mod.kind}: term rows must have shape (n, {n}), got {T.shape}")
                for name, add, target in (("M", t.M, M), ("C", t.C, C), ("K", t.K, K)):
                    if add is None:
                        continue
                    add = np.asarray(add)
                    if add.shape != (T.shape[0],) * 2:
                        raise ModelError(f"{mod.kind}: {name} must be {T.shape[0]}x{T.shape[0]}, got {add.shape}")
                    contrib = T.T @ add @ T
                    if target is K:
                        K += contrib
                    else:
                        if np.iscomplexobj(contrib) and np.any(contrib.imag):
                            raise ModelError(f"{mod.kind}: {name} must be real")
                        target += contrib.real
        if not np.any(K.imag):
            K = K.real
        return M, C, K

    @functools.cached_property
    def _solution(self) -> "_Solution":
        """Everything about the modified system that does not depend on the DOFs asked for.

        Solved once per model (the model is immutable) and reused by every
        :meth:`pole_residues` call: the modal terms no modification touches,
        and the coupled coordinates' poles with the maps from those
        coordinates to residues and mass line.
        """
        base = self.base_freqs_hz
        M, C, K = self._system(base)
        m = len(self)
        n = M.shape[0]
        # a modal coordinate no modification couples stays a closed-form modal term (exact, and keeps
        # repeated eigenvalues such as degenerate bending pairs out of the state-space eigensolver)
        w = 2 * np.pi * base
        dM, dC, dK = M.copy(), C.copy(), K.copy()
        dM[:m, :m] -= np.eye(m)
        dC[:m, :m] -= np.diag(2 * self.zeta * w)
        dK[:m, :m] -= np.diag(w**2)
        scale = np.ones(n)
        scale[:m] = np.maximum(w**2, 1.0)
        touched = ((np.abs(dK).max(axis=1, initial=0) > _DECOUPLED * scale)
                   | (np.abs(dC).max(axis=1, initial=0) > _DECOUPLED * np.sqrt(scale))
                   | (np.abs(dM).max(axis=1, initial=0) > _DECOUPLED))
        touched[m:] = True
        free = np.flatnonzero(~touched)
        if self.max_hz is not None:
            free = free[self.freqs_hz[free] <= self.max_hz]
        sel = np.flatnonzero(touched)
        if sel.size == 0:
            return _Solution(free, sel, np.zeros(0, complex), np.zeros((0, 0), complex), np.zeros((0, 0), complex),
                             np.zeros((0, 0)))
        poles, left, right, N, share = _solve_coupled(M[np.ix_(sel, sel)], C[np.ix_(sel, sel)], K[np.ix_(sel, sel)],
                                                      identity_mass=_identity_mass(M, sel, m))
        if self.pins_test_modes:
            poles, factor = self._pin(poles, sel, share)
            left = left * factor[None, :]
        if self.max_hz is not None:
            inside = np.abs(poles) <= 2 * np.pi * self.max_hz
            poles, left, right = poles[inside], left[:, inside], right[inside]
        return _Solution(free, sel, poles, left, right, N)

    def pole_residues(self, outputs, inputs=None) -> PoleResidues:
        """Poles and residues of the receptance from ``inputs`` to ``outputs`` (eqs. 2.28–2.30 solved once).

        Parameters
        ----------
        outputs, inputs : sequence of DOF specs
            Names (``"contact_L:z"``), thesis numbers 1–12, :class:`Dof`
            objects (e.g. from :func:`~receptance.dofs.dofs_from_channels`).
            ``inputs`` defaults to ``outputs``.

        Returns
        -------
        PoleResidues
        """
        out_dofs = [self.dof(s) for s in (outputs if not isinstance(outputs, (str, Dof, int)) else [outputs])]
        in_specs = outputs if inputs is None else inputs
        in_dofs = [self.dof(s) for s in (in_specs if not isinstance(in_specs, (str, Dof, int)) else [in_specs])]
        To, Ti = self._rows_of(out_dofs), self._rows_of(in_dofs)
        labels_o, labels_i = tuple(d.label for d in out_dofs), tuple(d.label for d in in_dofs)
        sol = self._solution
        free, sel = sol.free, sol.sel
        pr = PoleResidues.from_modes(self.freqs_hz[free], self.zeta[free], To[:, free], Ti[:, free], labels_o,
                                     labels_i)
        if sel.size == 0:
            return replace(pr, history=(f"{self.name}: modal sum of {len(self)} modes",))
        To_s, Ti_s = To[:, sel], Ti[:, sel]
        residues = (To_s @ sol.left)[:, None, :] * (sol.right @ Ti_s.T).T[None, :, :]
        mass_line = (To_s @ sol.mass_basis) @ (Ti_s @ sol.mass_basis).T
        return PoleResidues(np.concatenate([pr.poles, sol.poles]), np.concatenate([pr.residues, residues], axis=2),
                            pr.mass_line + mass_line, labels_o, labels_i,
                            history=(f"{self.name}: {free.size} modal terms + {sel.size} coupled coordinates "
                                     f"({len(self.modifications)} modification(s))",))

    @property
    def pins_test_modes(self) -> bool:
        """True when every modification is an effect present during the modal test.

        The test's frequencies and damping already contain such an effect (the
        rig springs, the bearings, the sensors' mass were there when the
        wheelset was hit), so after adding it the modes that carry the test's
        values keep them: the effect changes shapes and adds modes, it does not
        move the measured ones a second time.  In-service modifications (the
        primary suspension) do move them.
        """
        return bool(self.modifications) and all(getattr(m, "in_test", False) for m in self.modifications)

    def _assign(self, poles, sel, share) -> dict[int, tuple[float, float]]:
        """Which poles carry a measured mode: pole index -> the test's ``(f_hz, zeta)``.

        First the paired modes: each test mode (coordinates with the same test
        frequency and damping form one group — a degenerate cluster, which a
        modification mixes) claims as many poles as it has coordinates, by a
        one-to-one assignment maximising the group's share of the kinetic
        energy the FE coordinates hold in the pole, less half the log distance
        from the test frequency; below a third the pole is no partner (the
        effect has turned that mode into another one).  Then
        each remaining pole takes the measured mode without FE partner
        (:attr:`test_only`) nearest in frequency, if within
        :data:`TEST_ONLY_RTOL`.  Only poles with positive imaginary part are
        listed (their conjugates follow them).
        """
        m = len(self)
        groups: dict[tuple, list[int]] = {}
        for j, c in enumerate(sel):
            if c < m and self.origin[c] == "test":
                groups.setdefault((self.freqs_hz[c], self.zeta[c]), []).append(j)
        upper = np.flatnonzero(poles.imag > 0)
        targets: dict[int, tuple[float, float]] = {}
        if upper.size == 0:
            return targets
        if groups:
            # energy shares among the FE coordinates only: an added body (a wheel on its seat) may carry most
            # of a mode's kinetic energy while the FE coordinate still says which mode it is
            fe_rows = np.flatnonzero(np.asarray(sel) < m)
            fe_share = share / np.maximum(share[fe_rows].sum(axis=0, keepdims=True), np.finfo(float).tiny)
            f_pole = np.abs(poles[upper]) / (2 * np.pi)
            slots = [key for key, rows in groups.items() for _ in rows]
            gain = np.array([[fe_share[groups[key], k].sum() for k in upper] for key in slots])
            # among equally owned poles the one nearest the test frequency is the partner
            gain = gain - 0.5 * np.abs(np.log(np.array([f for f, _ in slots])[:, None] / f_pole[None, :]))
            for r, c in zip(*scipy.optimize.linear_sum_assignment(-gain)):
                if gain[r, c] >= 1 / 3:
                    targets[int(upper[c])] = slots[r]
        free = np.array([k for k in upper if k not in targets], int)
        if self.test_only and free.size:
            # nearest measured mode; not one-to-one: a test sees one mode where a symmetric part has two
            # (the axlebox rocking about x and about z)
            f_pole = np.abs(poles[free]) / (2 * np.pi)
            f_test = np.array([f for f, _ in self.test_only])
            dist = np.abs(np.log(f_test[:, None] / f_pole[None, :]))
            nearest = dist.argmin(axis=0)
            for c, r in enumerate(nearest):
                if dist[r, c] <= np.log1p(TEST_ONLY_RTOL):
                    targets[int(free[c])] = self.test_only[r]
        return targets

    def _pin(self, poles, sel, share):
        """Give the poles that carry a measured mode (:meth:`_assign`) its test frequency and damping.

        Returns the new poles and, per pole, the factor its residue takes: the
        residue of a pair scales with ``1 / Im(pole)`` so that the
        mass-normalised shape is kept.
        """
        poles = poles.copy()
        factor = np.ones(poles.size)
        for k, (f, z) in self._assign(poles, sel, share).items():
            w = 2 * np.pi * f
            new = -z * w + 1j * w * np.sqrt(1 - z * z)
            # the conjugate partner moves with it
            partner = int(np.argmin(np.abs(poles - np.conj(poles[k]))))
            for idx, target in ((k, new), (partner, np.conj(new))):
                factor[idx] *= poles[idx].imag / target.imag
                poles[idx] = target
        return poles, factor

    def _corrected_base(self) -> np.ndarray:
        """Base frequencies of a model mixing effects present in the test with in-service modifications.

        The test's frequencies already contain the lab effects (a bearing, a
        press fit), so they cannot be the base of a model that adds those
        effects again together with the primary suspension.  The lab
        configuration (design FE + lab effects) is solved as physics and each
        test mode's pole is found as :meth:`_assign` does; the ratio of its
        test frequency to that pole's frequency — what the test corrects in
        the design physics — multiplies the FE frequencies of the mode's
        coordinates.  The in-service model is then solved from these corrected
        frequencies plus every modification, unpinned: a lab model without
        in-service modifications reproduces the test's frequencies, and the
        in-service modifications move the modes from there.  Test modes whose
        pole the lab effects turned into another mode keep the test frequency.
        """
        lab = replace(self, modifications=tuple(mod for mod in self.modifications if getattr(mod, "in_test", False)))
        base = lab.base_freqs_hz.copy()
        M, C, K = lab._system(base)
        m = len(self)
        sel = np.arange(M.shape[0])
        poles, _, _, _, share = _solve_coupled(M, C, K, identity_mass=_identity_mass(M, sel, m))
        out = self.freqs_hz.copy()
        f_of_group: dict[tuple, list[float]] = {}
        for k, key in lab._assign(poles, sel, share).items():
            f_of_group.setdefault(key, []).append(float(np.abs(poles[k]) / (2 * np.pi)))
        for j in range(m):
            if self.origin[j] != "test":
                continue
            key = (self.freqs_hz[j], self.zeta[j])
            if key in f_of_group and base[j] > 0:
                out[j] = base[j] * key[0] / float(np.mean(f_of_group[key]))
        return out

    def for_service(self) -> "ModalModel":
        """The model without what belonged to the test only: the wheelset as it runs in service.

        Modifications whose ``role`` is ``"test_artefact"`` (rig springs,
        sensor masses) are removed; wheelset properties found in the lab (a
        bearing, a press fit) are kept; channel terms (residuals and measured
        modes fitted at the test's sensors) have no shape away from those
        sensors and are removed too.  Add the primary suspension afterwards:
        the test frequencies are then corrected as :meth:`base_freqs_hz` says.
        """
        kept = tuple(mod for mod in self.modifications if getattr(mod, "role", "wheelset") != "test_artefact")
        dropped = [mod.kind for mod in self.modifications if mod not in kept]
        step = "for service: " + (f"removed test artefacts {dropped}" if dropped else "no test artefact to remove")
        if self.channel_terms:
            step += f"; removed {len(self.channel_terms)} channel term set(s) fitted at the test's sensors"
        return replace(self, modifications=kept, channel_terms=(), history=self.history + (step,))

    # ------------------------------------------------------------- responses
    def receptance(self, outputs, inputs=None, freqs_hz=None, *, quantity: str = "receptance",
                   decay: float = 0.0) -> FrequencyResponse:
        """Receptance (or mobility, accelerance) between named DOFs, vectorised over frequency.

        Parameters
        ----------
        outputs, inputs : DOF specs
            See :meth:`pole_residues`; ``inputs`` defaults to ``outputs``.
        freqs_hz : array_like
            Frequency axis [Hz].
        quantity : {"receptance", "mobility", "accelerance"}
        decay : float, optional
            Exponential-window decay [1/s] of a measurement to compare with.
        """
        if freqs_hz is None:
            raise ModelError("give freqs_hz, the frequency axis to evaluate the receptance on")
        return self.pole_residues(outputs, inputs).evaluate(freqs_hz, quantity, decay=decay)

    def frf_at_channels(self, channels: pd.DataFrame, freqs_hz, *, decay: float = 0.0,
                        quantity: str = "accelerance", dofs: tuple | None = None) -> FrequencyResponse:
        """The model's FRFs at the sensors of a channel table, driven at its force channel.

        This is the model's counterpart of a measured H1 (thesis Figs. 3.18–3.19):
        outputs are the acceleration channels (names), the input is the force
        channel, along the directions and positions of the table.

        Parameters
        ----------
        channels : pandas.DataFrame
            Channel table with exactly one ``force`` row.
        freqs_hz : array_like
        decay : float, optional
            Exponential-window decay of the measurement [1/s] (its FRF's ``exp_window_decay``).
        quantity : str, optional
            Default ``"accelerance"``.
        dofs : (list of Dof, list of Dof), optional
            The table's acceleration and force DOFs already parsed
            (:func:`~receptance.dofs.dofs_from_channels`), for callers that
            evaluate many models on one table.
        """
        force = channels[channels["quantity"] == "force"]
        if len(force) != 1:
            raise ModelError(f"the channel table must have exactly one force row, found {len(force)}")
        acc = channels[channels["quantity"] == "acceleration"].reset_index(drop=True)
        outs, ins = dofs if dofs is not None else (dofs_from_channels(acc), dofs_from_channels(force))
        setup = ""
        if "setup" in acc and acc["setup"].notna().any():
            setup = str(acc["setup"].dropna().iloc[0])
        H = self.pole_residues(outs, ins).evaluate(freqs_hz, quantity, decay=decay, channels=acc)
        return self._with_channel_terms(H, setup, decay, quantity)

    def channel_accelerance(self, outputs, inputs, freqs_hz, *, decay: float = 0.0, setup: str = "") -> np.ndarray:
        """``(n_out, n_freq)`` accelerance from ``inputs[0]`` to ``outputs`` with the channel terms of ``setup``.

        The bare array behind :meth:`frf_at_channels` for callers that evaluate
        many models on the same parsed DOFs (a fit): no table handling.
        """
        H = self.pole_residues(outputs, inputs).evaluate(freqs_hz, "accelerance", decay=decay)
        return self._with_channel_terms(H, setup, decay, "accelerance").data[:, 0]

    def _with_channel_terms(self, H: FrequencyResponse, setup: str, decay: float, quantity: str
                            ) -> FrequencyResponse:
        terms = [t for t in self.channel_terms if t.setup in ("", setup)]
        if not terms:
            return H
        s = 2j * np.pi * H.freqs_hz + float(decay)
        names = list(H.outputs)
        extra = sum(t.receptance(names, s) for t in terms)
        data = H.data + (extra * s ** QUANTITIES[quantity][0])[:, None, :]
        return H.with_history(f"+ {len(terms)} channel term set(s)", data=data)

    def modes(self) -> pd.DataFrame:
        """Natural frequencies and damping of the (modified) system: one row per oscillating mode.

        Columns ``f_hz`` (undamped, ``|λ|/2π``), ``zeta``, ``f_damped_hz``
        (``Im λ/2π``); sorted by frequency.  Real (overdamped) poles are
        listed with ``f_damped_hz = 0``; unrestrained rigid-body motions are
        not poles and are counted in the log.
        """
        pr = self.pole_residues([], [])
        keep = pr.poles.imag >= 0
        df = pd.DataFrame({"f_hz": pr.natural_frequencies_hz[keep], "zeta": pr.damping_ratios[keep],
                           "f_damped_hz": pr.poles.imag[keep] / (2 * np.pi)})
        return df.sort_values("f_hz", kind="stable").reset_index(drop=True)


def _identity_mass(M: np.ndarray, sel: np.ndarray, m: int) -> np.ndarray:
    """Per coupled coordinate, the mass that says which coordinate a pole is: 1 for a design mode (its own
    mass-normalised modal mass), the diagonal of ``M`` for an added body.

    A modification that takes mass off FE nodes lowers the diagonal of the FE coordinates; a floating wheel takes
    off its whole rotary inertia, and with a layout slightly heavier than the FE's wheel the torsion coordinate's
    diagonal turns negative (lab freight wheelset, 340 kg wheel: 0.041 at 320 kg, -0.019 at 340 kg), so a share
    weighted by it would disown the torsion mode and pin its test frequency to another pole. Which design mode a
    pole is, is its participation, not that diagonal.
    """
    w = np.diag(M)[sel].copy()
    w[np.asarray(sel) < m] = 1.0
    return w


def _solve_coupled(M, C, K, identity_mass=None):
    """Poles of a small coupled system in coordinates, with the maps to residues and mass line.

    Returns ``poles`` (2p,), ``left`` (n, 2p) and ``right`` (2p, n) such that
    the residue of pole k between DOF rows ``To`` and ``Ti`` (over these
    coordinates) is ``(To @ left[:, k]) (right[k] @ Ti.T)``; ``mass_basis`` (n, r)
    mass-normalised unrestrained rigid-body directions (mass line
    ``(To N)(Ti N)ᵀ``); ``share`` (n, 2p) the share of each coordinate in
    each pole, ``|v|²`` weighted by ``identity_mass`` (default the diagonal of
    ``M``: its kinetic energy without cross terms).
    """
    n = M.shape[0]
    # unrestrained rigid-body directions: null space of K and C together; they give a mass line
    stacked = np.vstack([K, C])
    _, s, vh = np.linalg.svd(stacked)
    tol = 1e-10 * max(s[0] if s.size else 0.0, 1.0)
    rank = int(np.sum(s > tol))
    N = vh[rank:].conj().T.real if rank < n else np.zeros((n, 0))
    if N.shape[1]:
        mn = N.T @ M @ N
        ev, evec = np.linalg.eigh(mn)
        if ev.min() <= 0:
            raise ModelError("a rigid-body motion of the modified model has no mass; check mass modifications")
        N = N @ evec / np.sqrt(ev)
        P = scipy.linalg.null_space(N.T @ M)
    else:
        P = np.eye(n)
    p = P.shape[1]
    if p == 0:
        return np.zeros(0, complex), np.zeros((n, 0), complex), np.zeros((0, n), complex), N, np.zeros((n, 0))
    Mp, Cp, Kp = P.T @ M @ P, P.T @ C @ P, P.T @ K @ P
    Minv = np.linalg.inv(Mp)
    A = np.zeros((2 * p, 2 * p), complex)
    A[:p, p:] = np.eye(p)
    A[p:, :p] = -Minv @ Kp
    A[p:, p:] = -Minv @ Cp
    B = np.zeros((2 * p, p), complex)
    B[p:] = Minv
    lam, V = scipy.linalg.eig(A, overwrite_a=True, check_finite=False)
    lu = scipy.linalg.lu_factor(V, check_finite=False)
    W = scipy.linalg.lu_solve(lu, B, check_finite=False)  # (2p, p): V⁻¹ B
    left = P @ V[:p]  # (n, 2p)
    right = W @ P.T  # (2p, n)
    # reciprocal condition number of V from its LU factors (LAPACK gecon): cheap, and only a warning depends on it
    gecon = scipy.linalg.lapack.get_lapack_funcs("gecon", (lu[0],))
    rcond, _ = gecon(lu[0], np.abs(V).sum(axis=0).max(), norm="1")
    if rcond < 1e-10:
        log.warning("the modified model's eigenvectors are nearly dependent (condition %.1e); receptances may be "
                    "inaccurate near repeated modes", 1 / max(rcond, 1e-300))
    # which coordinate each pole lives in: kinetic-energy share of its eigenvector (> 1/2 names an owner)
    energy = np.abs(left) ** 2 * (np.diag(M) if identity_mass is None else np.asarray(identity_mass))[:, None]
    share = energy / np.maximum(energy.sum(axis=0, keepdims=True), np.finfo(float).tiny)
    return lam, left, right, N, share


@dataclass(frozen=True)
class _Solution:
    """The DOF-independent part of a solved model (see :attr:`ModalModel._solution`)."""

    free: np.ndarray
    sel: np.ndarray
    poles: np.ndarray
    left: np.ndarray
    right: np.ndarray
    mass_basis: np.ndarray
