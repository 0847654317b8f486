"""The contract every localization method fulfils.

A method answers, for a batch of secondary rays, *which direction of the distance impostor to look up* so that the
looked-up environment point stands in for the ray's true hit.

Inputs (all on one backend ``B``, float32, N rays):
    x : V3   ray origins relative to the reference point o of the impostor (world units, metres)
    R : V3   unit ray directions
    env : EnvMap  the impostor bound to ``B``; ``env.distance(v)`` is |v'| (the stored distance in direction v),
                  ``env.lookup(v)`` gives (r, g, b, distance)

Output of :meth:`Method.localize`: a :class:`Localization` with
    l : V3        the lookup vector, relative to o (not normalised; for the paper's method the hit estimate l)
    valid : (N,)  bool, False where the method found no hit (then the shown point is NaN); ``trace`` also
                  clears it for rays whose origin is not inside the environment as seen from o

:meth:`Method.trace` adds what every method shares, from one more lookup in direction l: the shown point
o + l̂·|l'| (returned relative to o), its radiance, and the diagnostic |l|/|l'| (1 = l lies on the environment
surface; for ``classical`` it is 1/|R'| and carries no meaning). Methods are registered by name (``@register``) and take
their parameters as keyword arguments, validated by the class's ``Params`` model (unknown names are errors).

What the harness needs to know about a method it reads from the class, never from parameter names:
    knob : Knob | None     the one parameter that trades cost for accuracy and the ladder of values that error
                           curves, the bench and claims try (None: the method has no such parameter)
    lookups_per_ray()      the cost measure of the method-comparison table
    layers_needed()        depth layers of the impostor it searches (captured by the caller when > 1)
    views_needed()         every view it searches (:class:`study.impostor.views.Views`: layers, probe sets, the
                           camera's buffer); by default the layers of ``layers_needed()``

Scene knowledge (optional): ``env.info`` is a dict that the caller (``study.measure.case``) fills with what it knows; a
method must still run when a key is missing (on a bare impostor, as in the analytic tests) and says what it falls
back to. Keys, all in world coordinates (metres):
    "reference" : (3,) the reference point o (methods work relative to it)
    "room"      : ((3,), (3,)) the room box (min, max): the proxy box (``reference.box``, else the environment's bounds)
    "open"      : bool, some texels of the impostor see no surface (distance ``cubemap.FAR``: an open environment);
                  then :meth:`Method.trace` lets a ray that a method found no hit for, and whose direction R sees no
                  surface from o, escape: shown at infinity in direction R with the background's radiance
    "layers"    : list[EnvMap] the layered impostor, nearest layer first (see :mod:`study.impostor.layers`);
    present when
                  some method's :meth:`Method.layers_needed` asked for more than one layer
    "probes"    : {ProbeSpec: ProbeSet} cube maps at several points, probe 0 the impostor
    (:mod:`study.impostor.probes`);
                  one set per :class:`~study.impostor.views.ProbeSpec` some method's views_needed() asked for
    "screen"    : ScreenView the camera's depth and colour buffer (:mod:`study.impostor.screen`), when asked for

A method that reads the shown point or its radiance from another view than ``env`` overrides :meth:`Method.trace`
(as ``layered``, ``ssr`` and ``multi_probe`` do): the shown point is then the hit it found, its radiance read from
the view that saw it.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict, ValidationError

from study.backend import V3, Backend
from study.errors import StudyError
from study.impostor.cubemap import FAR, FAR_MIN
from study.impostor.envmap import EnvMap
from study.impostor.views import Views
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


@dataclass
class Trace:
    l: V3  # lookup vector from the reference point
    shown: V3  # shown point relative to the reference point: l̂ |l'|
    radiance: V3  # RGB read from the impostor in direction l
    ratio: Any  # final |l| / |l'|
    valid: Any  # hit found


class Method(ABC):
    name: ClassVar[str]
    Params: ClassVar[type[BaseModel]] = NoParams
    knob: ClassVar[Knob | None] = None

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
    def localize(self, B: Backend, env: EnvMap, x: V3, R: V3) -> Localization:
        """Find the lookup vector for each ray (see the module docstring for the contract)."""

    @abstractmethod
    def lookups_per_ray(self) -> int:
        """Cube-map lookups this method spends per ray (the cost measure of the method-comparison table)."""

    def layers_needed(self) -> int:
        """Depth layers of the impostor this method searches (the caller captures that many into
        ``env.info["layers"]`` when more than one is asked for); 1 for the plain impostor."""
        return 1

    def views_needed(self) -> Views:
        """The views this method searches (:mod:`study.impostor.views`); the caller merges the requests of all
        methods of a case, captures them and puts them into ``env.info``. Default: ``layers_needed()`` layers."""
        return Views(layers=self.layers_needed())

    def trace(self, B: Backend, env: EnvMap, x: V3, R: V3, *, check_origin: bool = True) -> Trace:
        """Localize, then read the shown point and its radiance. With ``check_origin`` (one more lookup, not
        counted in :meth:`lookups_per_ray`), rays whose origin lies beyond the environment surface as seen from
        the reference point (|x| > |x'|: outside the room, inside geometry, or hidden behind it) are flagged
        invalid rather than shaded: no method can localize them."""
        loc = self.localize(B, env, x, R)
        if getattr(env, "info", {}).get(
            "open"
        ):  # open environment: a ray with no hit whose direction sees no surface escapes
            escape = ~loc.valid & (env.distance(R) >= FAR_MIN)  # (one more lookup, only where it is open)
            loc = Localization(
                V3(
                    *(
                        B.select(escape, c * FAR, a)
                        for c, a in zip((R.x, R.y, R.z), (loc.l.x, loc.l.y, loc.l.z))
                    )
                ),
                loc.valid | escape,
            )
        valid = loc.valid & B.isfinite(B.length(R))
        if check_origin:
            valid = valid & (B.length(x) <= env.distance(x) * 1.0001 + 1e-6)  # x is an undershoot
        # ----------------------------------------------------------- shown point and its radiance
        r, g, b, dist = env.lookup(loc.l)
        lhat = B.normalize(loc.l)
        nan = float("nan")
        shown = V3(*(B.select(valid, c * dist, nan) for c in (lhat.x, lhat.y, lhat.z)))
        rad = V3(*(B.select(valid, c, nan) for c in (r, g, b)))
        return Trace(loc.l, shown, rad, B.length(loc.l) / dist, valid)


class TracingMethod(Method):
    """A method that finds its shown point itself (it overrides :meth:`Method.trace`, e.g. searching other views
    than the impostor): its lookup vector is that shown point, from a trace without the origin check."""

    def localize(self, B: Backend, env: EnvMap, x: V3, R: V3) -> Localization:
        tr = self.trace(B, env, x, R, check_origin=False)
        return Localization(l=tr.shown, valid=tr.valid)


REGISTRY: dict[str, type[Method]] = {}


def register(cls: type[Method]) -> type[Method]:
    """Class decorator: make a method available by its ``name``."""
    if cls.name in REGISTRY and REGISTRY[cls.name] is not cls:
        raise RuntimeError(f"two methods are called {cls.name!r}")
    REGISTRY[cls.name] = cls
    return cls
