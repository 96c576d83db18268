"""One-dimensional (vertical) lumped mass-spring-damper networks and their linear equations.

A network is a set of point masses joined by links (a spring and a damper in parallel). Nodes can
be free (a mass), fixed (the wheel hub clamped to the shaker frame, or the ground) or the *base*:
the shaker plate or four-post post whose displacement is prescribed. External forces may act on
named free nodes (the hammer test).

Sign conventions (shared/DESIGN.md, paper section 3): z is upward; a link force is positive in
compression, ``F = k (z_lower - z_upper) + d (v_lower - v_upper)``, pushing its upper node up and its
lower node down. The contact force is the force the base exerts upward on the specimen.

The equations are assembled from the elements, never typed per model:
``M q'' + D q' + K q = -K_b z_b - D_b v_b + P f``, and every output (node motion, link force,
contact and plate force) is one row of coefficients over the physical quantities
``[q, v, a, z_b, v_b, a_b, f]``. The same rows give the frequency response (from the dynamic
stiffness, robust for very stiff sensors) and the state-space form used for time simulation.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from bench.models.linear_system import LinearSystem

BASE_INPUTS = ("z_base", "v_base", "a_base")


@dataclass(frozen=True)
class Mass:
    """A free point mass."""

    name: str
    mass_kg: float


@dataclass(frozen=True)
class Link:
    """A spring and a damper in parallel between a lower and an upper node."""

    name: str
    lower: str
    upper: str
    stiffness_n_per_m: float
    damping_ns_per_m: float = 0.0


@dataclass(frozen=True)
class Base:
    """The node with prescribed motion (shaker plate or post).

    ``contact_mass_kg`` is specimen mass that moves rigidly with the base (the tyre tread in
    Models 2 and 3): it is on the specimen side of the contact, so the contact force includes its
    inertia. ``plate_mass_kg`` is the bench's own plate above its load cell: the raw plate force
    includes its inertia and needs the plate-mass (m_comp) correction.
    """

    name: str = "base"
    contact_mass_kg: float = 0.0
    plate_mass_kg: float = 0.0


@dataclass(frozen=True)
class _OutputRow:
    """Coefficients of one output over [q, v, a] (free nodes) and u = [z_b, v_b, a_b, f...]."""

    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    u: np.ndarray


@dataclass
class MechanicalNetwork:
    """A vertical lumped network; see the module docstring for conventions."""

    masses: Sequence[Mass]
    links: Sequence[Link]
    base: Base | None = None
    fixed: Sequence[str] = ("ground",)
    force_inputs: Sequence[str] = ()
    _rows: dict[str, _OutputRow] = field(init=False, repr=False)  # filled on first use

    def __post_init__(self) -> None:
        self.masses = tuple(self.masses)
        self.links = tuple(self.links)
        self.fixed = tuple(self.fixed)
        self.force_inputs = tuple(self.force_inputs)
        self._validate()
        self._free = [m.name for m in self.masses]
        self._index = {name: i for i, name in enumerate(self._free)}
        self._nodes = {*self._free, *self.fixed, *([self.base.name] if self.base is not None else [])}
        self._links = {link.name: link for link in self.links}
        self._input_names = (BASE_INPUTS if self.base is not None else ()) + tuple(
            f"f_{node}" for node in self.force_inputs
        )
        self._assemble()
        self._rows = {}

    # ----------------------------------------------------------------------------- structure
    def _validate(self) -> None:
        names = [m.name for m in self.masses] + list(self.fixed)
        if self.base is not None:
            names.append(self.base.name)
        if len(set(names)) != len(names):
            raise ValueError(f"node names must be unique, got {names}")
        for m in self.masses:
            if not m.mass_kg > 0:
                raise ValueError(f"mass {m.name!r} must be positive, got {m.mass_kg} kg")
        link_names = [link.name for link in self.links]
        if len(set(link_names)) != len(link_names):
            raise ValueError(f"link names must be unique, got {link_names}")
        for link in self.links:
            for end in (link.lower, link.upper):
                if end not in names:
                    raise ValueError(f"link {link.name!r} joins unknown node {end!r}")
            if link.stiffness_n_per_m < 0 or link.damping_ns_per_m < 0:
                raise ValueError(f"link {link.name!r} has a negative stiffness or damping")
        for node in self.force_inputs:
            if node not in [m.name for m in self.masses]:
                raise ValueError(f"force input on {node!r}, which is not a free mass")

    @property
    def input_names(self) -> tuple[str, ...]:
        """Inputs of the state-space form: base motion (if any), then external forces."""
        return self._input_names

    @property
    def output_names(self) -> tuple[str, ...]:
        nodes = [*self._free, *self.fixed] + ([self.base.name] if self.base is not None else [])
        motion = [f"{prefix}_{node}" for node in nodes for prefix in "zva"]
        forces = [f"f_{link.name}" for link in self.links]
        return tuple(motion + forces + (["f_contact", "f_plate"] if self.base is not None else []))

    def _assemble(self) -> None:
        """Mass, stiffness and damping matrices of free nodes, and their coupling to the base."""
        n = len(self._free)
        self.M = np.diag([m.mass_kg for m in self.masses])
        self.K = np.zeros((n, n))
        self.D = np.zeros((n, n))
        self.K_base = np.zeros(n)
        self.D_base = np.zeros(n)
        base_name = self.base.name if self.base else None
        for link in self.links:
            for this, other in ((link.lower, link.upper), (link.upper, link.lower)):
                if this not in self._index:
                    continue
                i = self._index[this]
                self.K[i, i] += link.stiffness_n_per_m
                self.D[i, i] += link.damping_ns_per_m
                if other in self._index:
                    j = self._index[other]
                    self.K[i, j] -= link.stiffness_n_per_m
                    self.D[i, j] -= link.damping_ns_per_m
                elif other == base_name:
                    self.K_base[i] -= link.stiffness_n_per_m
                    self.D_base[i] -= link.damping_ns_per_m
        n_in = len(self.input_names)
        # Generalised force on the free nodes per input: -K_b z_b - D_b v_b + P f.
        self.F_in = np.zeros((n, n_in))
        if self.base is not None:
            self.F_in[:, 0] = -self.K_base
            self.F_in[:, 1] = -self.D_base
        offset = 3 if self.base is not None else 0
        for j, node in enumerate(self.force_inputs):
            self.F_in[self._index[node], offset + j] = 1.0

    # ----------------------------------------------------------------------------- outputs
    def _motion_row(self, node: str, order: int) -> _OutputRow:
        """Row for displacement (order 0), velocity (1) or acceleration (2) of a node."""
        n, n_in = len(self._free), len(self.input_names)
        rows = [np.zeros(n), np.zeros(n), np.zeros(n)]
        u = np.zeros(n_in)
        if node in self._index:
            rows[order][self._index[node]] = 1.0
        elif self.base is not None and node == self.base.name:
            u[order] = 1.0
        # fixed nodes: all zero
        return _OutputRow(rows[0], rows[1], rows[2], u)

    def _link_force_row(self, link: Link) -> _OutputRow:
        lo_z, up_z = self._motion_row(link.lower, 0), self._motion_row(link.upper, 0)
        lo_v, up_v = self._motion_row(link.lower, 1), self._motion_row(link.upper, 1)
        k, d = link.stiffness_n_per_m, link.damping_ns_per_m
        return _OutputRow(
            q=k * (lo_z.q - up_z.q) + d * (lo_v.q - up_v.q),
            v=k * (lo_z.v - up_z.v) + d * (lo_v.v - up_v.v),
            a=np.zeros(len(self._free)),
            u=k * (lo_z.u - up_z.u) + d * (lo_v.u - up_v.u),
        )

    def _row(self, name: str) -> _OutputRow:
        """The output's coefficient row, built on its first use: a describing-function balance
        asks for two outputs of a network it builds anew at every iteration."""
        row = self._rows.get(name)
        if row is None:
            row = self._rows[name] = self._build_row(name)
        return row

    def _build_row(self, name: str) -> _OutputRow:
        if self.base is not None and name in ("f_contact", "f_plate"):
            contact = self._contact_row()
            if name == "f_contact":
                return contact
            u = contact.u.copy()
            u[2] += self.base.plate_mass_kg
            return _OutputRow(contact.q, contact.v, contact.a, u)
        kind, _, subject = name.partition("_")
        if len(kind) == 1 and kind in "zva" and subject in self._nodes:
            return self._motion_row(subject, "zva".index(kind))
        if kind == "f" and subject in self._links:
            return self._link_force_row(self._links[subject])
        raise ValueError(f"unknown output {name!r}; available: {self.output_names}")

    def _contact_row(self) -> _OutputRow:
        """The force the base exerts on the specimen: the tread's inertia and every link to the
        base."""
        assert self.base is not None
        base = self._motion_row(self.base.name, 2)
        q, v, a, u = base.q, base.v, base.a, base.u * self.base.contact_mass_kg
        for link in self.links:
            sign = (link.lower == self.base.name) - (link.upper == self.base.name)
            if sign:
                r = self._row(f"f_{link.name}")
                q, v, u = q + sign * r.q, v + sign * r.v, u + sign * r.u
        return _OutputRow(q, v, a, u)

    # ----------------------------------------------------------------------------- evaluation
    def frequency_response(
        self,
        freq_hz: np.ndarray | float,
        input_name: str | None = None,
        outputs: Sequence[str] | None = None,
    ) -> dict[str, np.ndarray]:
        """Complex response of the outputs (all by default) per unit input at ``freq_hz``.

        ``input_name`` is ``"z_base"`` (per metre of base displacement, the default when the
        network has a base) or ``"f_<node>"`` (per newton of external force).
        """
        freq = np.atleast_1d(np.asarray(freq_hz, dtype=float))
        w = 2 * np.pi * freq
        if input_name is None:
            input_name = "z_base" if self.base is not None else self.input_names[0]
        n, n_in = len(self._free), len(self.input_names)
        u = np.zeros((freq.size, n_in), dtype=complex)
        if input_name == "z_base" and self.base is not None:
            u[:, 0], u[:, 1], u[:, 2] = 1.0, 1j * w, -(w**2)
        elif input_name in self.input_names and input_name not in BASE_INPUTS:
            u[:, self.input_names.index(input_name)] = 1.0
        else:
            raise ValueError(f"unknown input {input_name!r}; inputs: z_base or {self.input_names}")
        q = np.zeros((freq.size, n), dtype=complex)
        if n:
            dyn = self.K[None] + 1j * w[:, None, None] * self.D - (w**2)[:, None, None] * self.M
            force = u @ self.F_in.T
            q = np.linalg.solve(dyn, force[..., None])[..., 0]
        v, a = 1j * w[:, None] * q, -(w**2)[:, None] * q
        rows = {name: self._row(name) for name in (outputs if outputs is not None else self.output_names)}
        return {name: q @ r.q + v @ r.v + a @ r.a + u @ r.u for name, r in rows.items()}

    def state_space(self, outputs: Sequence[str] | None = None) -> LinearSystem:
        """State-space form with state ``[q, v]`` and inputs :attr:`input_names`."""
        names = tuple(outputs) if outputs is not None else self.output_names
        n = len(self._free)
        m_inv = np.linalg.inv(self.M) if n else np.zeros((0, 0))
        acc_x = np.hstack([-m_inv @ self.K, -m_inv @ self.D])
        acc_u = m_inv @ self.F_in
        A = np.vstack([np.hstack([np.zeros((n, n)), np.eye(n)]), acc_x])
        B = np.vstack([np.zeros((n, len(self.input_names))), acc_u])
        n_in, n_out = len(self.input_names), len(names)
        rows = [self._row(o) for o in names]
        C = np.array([np.concatenate([r.q, r.v]) for r in rows]).reshape(n_out, 2 * n)
        Dm = np.array([r.u for r in rows]).reshape(n_out, n_in)
        acc_rows = np.array([r.a for r in rows]).reshape(n_out, n)
        C = C + acc_rows @ acc_x
        Dm = Dm + acc_rows @ acc_u
        states = tuple(f"z_{m}" for m in self._free) + tuple(f"v_{m}" for m in self._free)
        return LinearSystem(A, B, C, Dm, inputs=self.input_names, outputs=names, states=states)

    def eigenfrequencies_hz(self) -> np.ndarray:
        """Undamped natural frequencies |lambda| / 2 pi of the oscillating modes, base held still."""
        lam = np.linalg.eigvals(self.state_space(outputs=()).A)
        return np.sort(np.abs(lam[lam.imag > 0])) / (2 * np.pi)
