"""The contract every localization method fulfils.

A method answers, for a batch of secondary rays, *which point of the environment stands in for each ray's hit*,
searching image-based views of the environment (the distance impostor first of all).

Inputs (all on one backend ``B``, float32, N rays):
    x : V3   ray origins relative to the reference point o of the impostor (world units, metres)
    R : V3   unit ray directions
    env : Captured  what the caller captured (:class:`study.impostor.views.Captured`): the impostor, which it reads
                    like an EnvMap (``env.distance(v)`` = |v'|, the stored distance in direction v; ``env.lookup(v)``
                    = (r, g, b, distance)), the other views asked for (layers, probe sets, the camera's buffer) and
                    the scene knowledge (reference point, room box, open environment). A bare impostor (an EnvMap)
                    may be passed to ``trace`` instead: the methods then use their documented fallbacks.

A method implements one of two searches:
    localize(B, env, x, R) → :class:`Localization` (l, valid, lookups): the lookup vector l relative to o (for the
        paper's method the hit estimate), False in valid where it found no hit, optionally the lookups each ray
        spent (default: ``lookups_per_ray`` − 1 on every ray); :meth:`Method.search` then reads the impostor in
        direction l: the shown point l̂·|l'|, its radiance and the diagnostic |l|/|l'| (1 = l lies on the
        environment surface). A zero lookup vector counts as no hit.
    search(B, env, x, R) → :class:`Found` (l, shown, radiance, ratio, valid, lookups): a method that reads another
        view than the impostor (``layered``, ``ssr``, ``multi_probe``, subclasses of :class:`TracingMethod`) finds
        the shown point and reads its radiance from the view that saw it; optionally ``flags``, per-ray diagnostics
        of its own ({column: boolean mask}, each column declared in :mod:`study.columns`; the row gets the fraction
        of rays where it holds, e.g. ``probe_blend``'s ghosting).
:meth:`Method.trace` then finishes every method alike (escape rule of open environments, origin check, NaN for
invalid rays) and returns a :class:`Trace` with the lookups each ray spent. Answers of the wrong shape or type are
one StudyError line naming the method (plug-ins are checked like the methods of this package).

What the harness needs to know about a method it reads from the class, never from parameter names:
    knob : Knob | None       the one parameter that trades cost for accuracy and the ladder of values that error
                             curves, the bench and claims try (None: the method has no such parameter)
    lookups_per_ray(res)     the most lookups one ray can spend at cube resolution res (an upper bound from the
                             parameters alone, for the budget and the bench's floor model); tables report the mean
                             of what the rays spent (``Trace.lookups``), which never exceeds it
    volume_lookups(res)      how many of those are 3D texture fetches (a distance field's; default 0)
    layers_needed()          depth layers of the impostor it searches (captured by the caller when > 1)
    views_needed()           every view it searches (:class:`study.impostor.views.Views`: layers, probe sets, the
                             camera's buffer); by default the layers of ``layers_needed()``

Families: a method with ``glossy = True`` (:mod:`study.methods.glossy`) shades rough objects; its radiance is the
average of the GGX lobe around R, read with ``Captured.lobe`` (roughness, normals). ``methods = "all"`` means the
mirror methods only, so mirror figures keep their cost and tables; ``methods = "glossy"`` means the glossy ones.

Methods are registered by name (``@register``; the labels of reference rows are reserved) and take their
parameters as keyword arguments, validated by the class's ``Params`` model (unknown names are errors).
"""

from __future__ import annotations

import inspect
import math
import re
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict, ValidationError

from study.backend import V3, Backend
from study.errors import StudyError, plugin_guard
from study.impostor.cubemap import FAR, FAR_MIN
from study.impostor.views import Captured, Views
from study.validation import first_error


@dataclass(frozen=True)
class Knob:
    """The parameter of a method that trades cost for accuracy, and the values curves and the bench try."""

    param: str  # name of the parameter in the method's Params
    ladder: tuple  # values tried by error-vs-cost curves, ``study bench`` and claims


class NoParams(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


@dataclass
class Localization:
    l: V3  # lookup vector from the reference point
    valid: Any  # hit found
    lookups: Any = None  # per ray: lookups the search spent (None: ``lookups_per_ray`` − 1 on every ray)


@dataclass
class Found:
    """What a method's own search (:meth:`Method.search`) found: the shown point, read from the view that saw it.

    l: the lookup vector (for a method that reads the impostor: the hit estimate); shown: the shown point, relative
    to o; radiance: its RGB; ratio: the diagnostic |l|/|l'| in the view read (NaN where it has no meaning); valid:
    a hit was found; lookups: per ray, every lookup spent, the shown point's read included."""

    l: V3
    shown: V3
    radiance: V3
    ratio: Any
    valid: Any
    lookups: Any
    flags: dict | None = (
        None  # {declared column: per-ray bool mask}: the row's column is its fraction of rays
    )


@dataclass
class Trace:
    l: V3  # lookup vector from the reference point
    shown: V3  # shown point relative to the reference point: l̂ |l'|
    radiance: V3  # RGB read from the impostor in direction l
    ratio: Any  # final |l| / |l'|
    valid: Any  # hit found
    lookups: Any = None  # per ray: the lookups spent (≤ lookups_per_ray(res))
    flags: dict | None = None  # the search's per-ray diagnostics (Found.flags)


class Method(ABC):
    name: ClassVar[str]
    Params: ClassVar[type[BaseModel]] = NoParams
    knob: ClassVar[Knob | None] = None
    glossy: ClassVar[bool] = False  # a method for rough objects (module docstring: families)
    #: False for a method that reads none of the reference point's views (the exact query, ``traced``): its rows
    #: leave out the columns measured against the cube map it does not read (``*_oracle``, the split ``dec_*``).
    reads_views: ClassVar[bool] = True

    def __init__(self, **params):
        try:
            self.params = self.Params(**params)
        except ValidationError as err:
            key, msg = first_error(err, self.Params)
            msg = "unknown parameter" if msg.startswith("unknown key") else msg
            allowed = ", ".join(self.Params.model_fields) or "none"
            raise StudyError(
                f"{msg} (parameters of {self.name!r}: {allowed})", key=f"method.{key}" if key else "method"
            ) from None

    def __repr__(self):
        args = ", ".join(f"{k}={v!r}" for k, v in self.params.model_dump().items())
        return f"{self.name}({args})"

    @property
    def label(self) -> str:
        """Label for tables and figures: the name, the knob's value and the other parameters that were set, e.g.
        'localized(iterations=10)'; just the name for a method without a knob and with nothing set."""
        shown = self.params.model_dump(exclude_unset=True)
        if self.knob is not None:
            shown = {
                self.knob.param: self.knob_value,
                **{k: v for k, v in shown.items() if k != self.knob.param},
            }
        args = ", ".join(f"{k}={v!r}" for k, v in shown.items())
        return f"{self.name}({args})" if args else self.name

    @property
    def knob_value(self):
        """The value of the cost/accuracy knob (None without a knob)."""
        return getattr(self.params, self.knob.param) if self.knob is not None else None

    def family(self) -> str:
        """The label without the knob: the curve this method belongs to in an error-vs-knob plot."""
        shown = {
            k: v
            for k, v in self.params.model_dump(exclude_unset=True).items()
            if self.knob is None or k != self.knob.param
        }
        args = ", ".join(f"{k}={v!r}" for k, v in shown.items())
        return f"{self.name}({args})" if args else self.name

    def with_knob(self, value) -> Method:
        """The same method with the knob set to ``value``."""
        params = {**self.params.model_dump(exclude_unset=True), self.knob.param: value}
        return type(self)(**params)

    def ladder(self) -> list[Method]:
        """This method at every value of its knob's ladder (itself alone without a knob)."""
        return [self.with_knob(v) for v in self.knob.ladder] if self.knob is not None else [self]

    @abstractmethod
    def localize(self, B: Backend, env: Captured, x: V3, R: V3) -> Localization:
        """Find the lookup vector for each ray (see the module docstring for the contract)."""

    @abstractmethod
    def lookups_per_ray(self, res: int | None = None) -> float:
        """The most cube-map lookups one ray can spend at cube resolution ``res`` (None: at any resolution): a
        bound from the parameters alone, what the budget and the bench's floor model count."""

    def lookup_bound(self, res: int | None = None) -> float:
        """:meth:`lookups_per_ray` at ``res`` (also for a plug-in whose ``lookups_per_ray`` takes no argument)."""
        takes_res = bool(inspect.signature(self.lookups_per_ray).parameters)
        v = self.lookups_per_ray(res) if takes_res else self.lookups_per_ray()
        try:
            bound = float(v)
        except (TypeError, ValueError):
            bound = math.nan
        if not (math.isfinite(bound) and bound >= 0):  # a NaN would pass every budget (NaN > limit is False)
            raise StudyError(
                f"lookups_per_ray() of {self.name!r} gave {v!r}; it must be a finite number of lookups ≥ 0 "
                "(the budget and the bench's floor model count it)",
                key="method",
            )
        return bound

    def host_steps(self, res: int | None = None) -> float:
        """Array steps this method takes at cube resolution ``res`` whatever the number of rays: a loop on the
        host over its iterations or samples, each step a few array operations over every ray. The budget prices
        each at a fixed cost on top of the lookups (:data:`study.harness.budget.SECONDS_PER_STEP`), which is what
        a method of many steps on few rays costs; 0 for a method whose cost is its lookups alone."""
        return 0.0

    def colour_lookups(self, res: int | None = None) -> float:
        """How many of :meth:`lookups_per_ray` also read a colour (a 4-channel texel: a blend of several probes'
        radiance reads each one's); 0 for a method that reads one colour, at the shown point, which the bench's
        floor always counts."""
        return 0.0

    def volume_lookups(self, res: int | None = None) -> float:
        """How many of :meth:`lookups_per_ray` are 3D texture fetches (a distance field's), which the bench's
        floor prices at the 3D fetch rate; 0 for a method that reads only cube maps and 2D buffers."""
        return 0.0

    def layers_needed(self) -> int:
        """Depth layers of the impostor this method searches (captured into ``Captured.layers`` when more than
        one is asked for); 1 for the plain impostor."""
        return 1

    def views_needed(self) -> Views:
        """The views this method searches (:mod:`study.impostor.views`); the caller merges the requests of all
        methods, captures them and hands them over as a :class:`Captured`. Default: ``layers_needed()`` layers."""
        return Views(layers=self.layers_needed())

    # ---------------------------------------------------------------------------------------------- the search
    def search(self, B: Backend, env: Captured, x: V3, R: V3) -> Found:
        """The hit of each ray and what it shows. Default: :meth:`localize`, then one lookup of the impostor in
        direction l gives the shown point l̂·|l'| and its radiance. A method that reads another view overrides
        this (its :class:`Found` carries the point, the radiance and the lookups it spent)."""
        loc = self.localize(B, env, x, R)
        self._check_answer(B, loc, x, Localization)
        valid = loc.valid & ~(B.length(loc.l) == 0.0)  # a zero lookup vector points nowhere: no hit
        finite = B.isfinite(B.length(loc.l))  # no lookup at a NaN or inf (its shown point stays NaN)
        l, Rs = loc.l, R
        r, g, b, dist = env.lookup(
            V3(*(B.select(finite, c, d) for c, d in zip((l.x, l.y, l.z), (Rs.x, Rs.y, Rs.z))))
        )
        lhat = B.normalize(loc.l)
        spent = loc.lookups if loc.lookups is not None else x.x * 0.0 + (self.lookup_bound(env.res) - 1)
        return Found(
            loc.l,
            V3(lhat.x * dist, lhat.y * dist, lhat.z * dist),
            V3(r, g, b),
            B.length(loc.l) / dist,
            valid,
            spent + 1.0,
        )

    def sees_origin(self, B: Backend, env: Captured, x: V3):
        """Rays whose origin the views see: |x| ≤ |x'| from o (not outside the room, inside geometry or hidden
        behind it). One more lookup, not counted in the lookups."""
        return B.length(x) <= env.distance(x) * 1.0001 + 1e-6

    #: The diagnostic ratio is NaN on invalid rays (else it is kept there, as the lookup methods' |l|/|l'|).
    ratio_where_valid: ClassVar[bool] = False

    # ---------------------------------------------------------------------------------------------- the finish
    def trace(self, B: Backend, env, x: V3, R: V3, *, check_origin: bool = True) -> Trace:
        """:meth:`search`, then the finishing step every method shares: rays with no hit in an open environment
        whose direction R sees no surface from o escape (shown at infinity along R with the background's
        radiance; one more lookup, not counted); rays with a non-finite direction, and with ``check_origin``
        rays whose origin the views do not see (:meth:`sees_origin`), are invalid; invalid rays show NaN.
        ``env``: a :class:`Captured`, or a bare impostor (an EnvMap: the methods' fallbacks apply)."""
        env = Captured.of(env)
        f = self._guarded(lambda: self.search(B, env, x, R))
        self._check_answer(B, f, x, Found)
        l, shown, rad, ratio, valid = f.l, f.shown, f.radiance, f.ratio, f.valid
        if env.open:  # a ray with no hit whose direction sees no surface escapes
            escape = ~valid & (env.distance(R) >= FAR_MIN)
            far = R * FAR
            r, g, b, dist = env.lookup(far)
            fhat = B.normalize(far)

            def sel(a: V3, b: V3) -> V3:
                return V3(*(B.select(escape, p, q) for p, q in zip((a.x, a.y, a.z), (b.x, b.y, b.z))))

            l, shown, rad = sel(far, l), sel(fhat * dist, shown), sel(V3(r, g, b), rad)
            ratio = B.select(escape, B.length(far) / dist, ratio)
            valid = valid | escape
        valid = valid & B.isfinite(B.length(R))
        if check_origin:
            valid = valid & self.sees_origin(B, env, x)
        nan = float("nan")
        shown = V3(*(B.select(valid, c, nan) for c in (shown.x, shown.y, shown.z)))
        rad = V3(*(B.select(valid, c, nan) for c in (rad.x, rad.y, rad.z)))
        if self.ratio_where_valid:
            ratio = B.select(valid, ratio, nan)
        flags = {k: v & valid for k, v in f.flags.items()} if f.flags else None  # on the rays it answers
        return Trace(l, shown, rad, ratio, valid, f.lookups, flags)

    # ---------------------------------------------------------------------------------------------- plug-ins
    def _guarded(self, call):
        """``call()``, with a plug-in's failures (and its ``sys.exit``) turned into one StudyError line."""
        return plugin_guard(
            call,
            plugin=is_plugin(type(self)),
            exited=lambda code: f"method {self.name!r} called sys.exit({code!r}) while tracing",
            failed=f"method {self.name!r} (plug-in {type(self).__module__}) failed",
        )

    def _check_answer(self, B: Backend, ans, x: V3, want: type) -> None:
        """The shape of a search's answer: a ``want`` (Localization or Found) of V3s of N floats and a boolean mask
        of N rays; anything else is a StudyError naming the method and what was wrong."""
        n = B.shape_of(x.x)[1]
        if not isinstance(ans, want):
            raise self._bad(f"returned {_what(ans)}, not a {want.__name__}")
        fields = ("l", "shown", "radiance") if want is Found else ("l",)
        for name in fields:
            v = getattr(ans, name)
            if not isinstance(v, V3):
                raise self._bad(f"returned {name} = {_what(v)}, not a V3 of the rays' points")
            for c in (v.x, v.y, v.z):
                self._check_array(B, c, n, f"{name}", "float")
        self._check_array(B, ans.valid, n, "valid", "bool")
        if ans.lookups is not None:
            self._check_array(B, ans.lookups, n, "lookups", "float")
        for name, mask in (getattr(ans, "flags", None) or {}).items():
            self._check_array(B, mask, n, f"flags[{name!r}]", "bool")

    def _check_array(self, B: Backend, a, n: int, name: str, kind: str) -> None:
        shape = B.shape_of(a)
        if shape is None:
            raise self._bad(f"returned {name} = {_what(a)}, not an array of one value per ray")
        if shape[0] != kind:
            raise self._bad(f"returned {name} as {shape[0]} values, not {kind}")
        if shape[1] != n:
            raise self._bad(f"returned {name} with {shape[1]} values for {n} rays")

    def _bad(self, what: str) -> StudyError:
        return StudyError(f"method {self.name!r} {what}", key="method")


def _what(v) -> str:
    return "None" if v is None else f"a {type(v).__name__}"


def is_plugin(cls: type) -> bool:
    """Whether a method class comes from outside study's own package (a plug-in)."""
    return not cls.__module__.startswith("study.methods.")


class TracingMethod(Method):
    """A method that finds its shown point itself (:meth:`Method.search`, e.g. in other views than the impostor):
    its lookup vector is that shown point, from a trace without the origin check."""

    @abstractmethod
    def search(self, B: Backend, env: Captured, x: V3, R: V3) -> Found:
        """The hit, the shown point and its radiance from the view that saw it, the lookups spent."""

    def localize(self, B: Backend, env: Captured, x: V3, R: V3) -> Localization:
        tr = self.trace(B, env, x, R, check_origin=False)
        return Localization(l=tr.shown, valid=tr.valid, lookups=tr.lookups)


REGISTRY: dict[str, type[Method]] = {}

#: Labels of reference rows in the tables (cases: oracle_map, truth_at_hit; figures: mitsuba; caustics: exact): no
#: method may be called so.
RESERVED = ("oracle_map", "truth_at_hit", "mitsuba", "exact")


def register(cls: type[Method]) -> type[Method]:
    """Class decorator: make a method available by its ``name`` (a StudyError for a reserved or taken name)."""
    name = getattr(cls, "name", None)
    if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
        raise StudyError(f"a method's name must be an identifier, got {name!r} ({cls.__qualname__})")
    if name in RESERVED:
        raise StudyError(f"{name!r} is the label of a reference row of the tables; name the method otherwise")
    old = REGISTRY.get(name)
    if (
        old is not None
        and old is not cls
        and (old.__module__, old.__qualname__) != (cls.__module__, cls.__qualname__)
    ):
        raise StudyError(
            f"a method called {name!r} is already registered (by {old.__module__}); name it otherwise"
        )
    REGISTRY[name] = cls
    return cls
