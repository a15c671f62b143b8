"""The parameter aggregate: the fluid, the air boundary and one table per registered component.

:class:`Parameters` derives from the registry (:data:`evtms.benches.BENCHES`):
each component's module declares its parameter table (a frozen dataclass of
fields with units and ranges, :mod:`evtms.params`) and its bench names the
table's default (:attr:`evtms.benches.base.Bench.parameters`); the table
takes the bench's name. A new component module and its registry line so get
a ``[name]`` table in parameter files (:func:`load_parameters`) and a
``name`` table in the ``parameters`` attribute of its LUTs
(:meth:`Parameters.component_json`, :func:`parameters_from_json`).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from evtms.benches import BENCHES
from evtms.errors import EvtmsInputError
from evtms.params import Environment, apply_tables, check_backend, check_fluid_name, check_table, read_params_toml

#: The tables of a parameter file: the air boundary, then one per registered component, named after its bench.
SECTIONS = ("environment", *BENCHES)


class _ParameterMethods:
    """What :class:`Parameters` does; its fields come from the registry."""

    def component_json(self, component: str) -> str:
        """The ``parameters`` attribute of a LUT of ``component``: its parameters as JSON."""
        return json.dumps(self.for_component(component), sort_keys=True)

    def environment_json(self) -> str:
        """The ``environment`` attribute of a LUT: the air boundary as JSON."""
        return json.dumps(dataclasses.asdict(self.environment), sort_keys=True)

    def for_component(self, component: str) -> dict[str, Any]:
        """The parameters one component's bench uses, as a plain dict."""
        return {
            "fluid": self.fluid,
            "backend": self.backend,
            component: dataclasses.asdict(getattr(self, component)),
        }

    def validate(self) -> None:
        """Check every parameter against its range and the relations between them.

        Raises
        ------
        EvtmsInputError
            One line like ``[condenser] n_tubes = -3 is not allowed; allowed: 1 <= n_tubes <= 1000
            (whole number)``.
        """
        check_fluid_name(self.fluid)
        check_backend(self.backend)
        for section in SECTIONS:
            check_table(getattr(self, section), f"[{section}]")

    def differences(self, other: Parameters, sections: Iterable[str] | None = None) -> list[str]:
        """Dotted names of the parameters whose values differ from ``other``'s.

        Parameters
        ----------
        other : Parameters
            The parameters to compare with.
        sections : iterable of str, optional
            Compare only these top-level names (``"fluid"``, ``"backend"``,
            ``"condenser"``, ...); all by default.

        Returns
        -------
        list of str
            For example ``["condenser.n_tubes", "fluid"]``, sorted.
        """
        a, b = _flatten(self), _flatten(other)
        keep = None if sections is None else set(sections)
        return sorted(
            k for k in a.keys() | b.keys() if (keep is None or k.split(".")[0] in keep) and a.get(k) != b.get(k)
        )

    def differences_from_lut(self, component: str, parameters_json: str) -> list[str]:
        """Dotted names where these parameters contradict a LUT's ``parameters`` attribute.

        Compares ``fluid``, ``backend`` and ``component``'s table with the
        values the LUT of ``component`` was computed with.

        Raises
        ------
        EvtmsInputError
            ``parameters_json`` is not a parameters attribute of ``component``.
        """
        component = component.replace("-", "_")
        lut = parameters_from_json(component, parameters_json)
        return self.differences(lut, ("fluid", "backend", component))


#: Docstring of :class:`Parameters` (the component tables listed from the registry).
_DOC = """Every parameter a bench or a cycle uses, with the spec's defaults.

    Attributes
    ----------
    fluid : str
        CoolProp fluid name (checked when the fluid is loaded).
    backend : str
        CoolProp backend, one of :data:`evtms.params.BACKENDS`.
    environment : evtms.params.Environment
        The ambient-air boundary.
    {names}
        One table per registered bench, named after it, its default the
        bench's ``parameters()``. With ``environment``, the tables of a
        parameter file (:data:`SECTIONS`).
    """

Parameters = dataclasses.make_dataclass(
    "Parameters",
    [
        ("fluid", str, dataclasses.field(default="R134a")),
        ("backend", str, dataclasses.field(default="HEOS")),
        ("environment", Environment, dataclasses.field(default_factory=Environment)),
        *(
            (name, type(bench.parameters()), dataclasses.field(default_factory=bench.parameters))
            for name, bench in BENCHES.items()
        ),
    ],
    bases=(_ParameterMethods,),
    namespace={"__module__": __name__, "__doc__": _DOC.format(names=", ".join(BENCHES))},
    frozen=True,
)


def _flatten(params: Parameters) -> dict[str, Any]:
    """``{"fluid": ..., "condenser.n_tubes": ..., ...}`` of ``params``."""
    out: dict[str, Any] = {}
    for key, value in dataclasses.asdict(params).items():
        if isinstance(value, dict):
            out.update({f"{key}.{k}": v for k, v in value.items()})
        else:
            out[key] = value
    return out


def parameters_from_dict(data: dict[str, Any]) -> Parameters:
    """The defaults with ``fluid``, ``backend`` and the tables of ``data`` (parsed TOML or JSON) applied, checked."""
    return apply_tables(data, Parameters(), SECTIONS)


def load_parameters(path: str | Path | None = None) -> Parameters:
    """Default parameters, overridden by a TOML file if ``path`` is given.

    Parameters
    ----------
    path : str or Path, optional
        A regular UTF-8 TOML file of at most :data:`evtms.params.MAX_PARAMS_BYTES` with
        top-level ``fluid``/``backend`` and tables named after the components.

    Raises
    ------
    EvtmsInputError
        One line naming the file and what is wrong: it is missing, not a
        regular file (a folder, a named pipe, a device), too large, empty,
        binary, not UTF-8 or not valid TOML; or it names an unknown table or
        parameter, or a value of the wrong type or outside its range, e.g.
        ``params file 'p.toml': [condenser] n_tubes = -3 is not allowed;
        allowed: 1 <= n_tubes <= 1000 (whole number)``.
    """
    if path is None:
        return Parameters()
    data = read_params_toml(path)
    try:
        return parameters_from_dict(data)
    except EvtmsInputError as exc:
        raise EvtmsInputError(f"params file {str(Path(path))!r}: {exc}") from None


def parameters_from_json(component: str, parameters_json: str, environment_json: str | None = None) -> Parameters:
    """The parameters a LUT of ``component`` records, the others at their defaults.

    Parameters
    ----------
    component : str
        The LUT's component (``condenser``, ``expansion_valve``, ...).
    parameters_json : str
        The LUT's ``parameters`` attribute (:meth:`Parameters.component_json`).
    environment_json : str, optional
        The LUT's ``environment`` attribute (:meth:`Parameters.environment_json`).

    Raises
    ------
    EvtmsInputError
        The text is not JSON of an object, or names another component, an
        unknown parameter or a value outside its range.
    """
    component = component.replace("-", "_")
    if component not in SECTIONS or component == "environment":
        allowed = ", ".join(s for s in SECTIONS if s != "environment")
        raise EvtmsInputError(f"unknown component {component!r}; allowed: {allowed}")
    params = Parameters()
    for attr, text, sections in (
        ("parameters", parameters_json, (component,)),
        ("environment", environment_json, ("environment",)),
    ):
        if text is None:
            continue
        try:
            data = json.loads(text)
        except (TypeError, ValueError) as exc:
            raise EvtmsInputError(f"LUT attribute {attr!r} is not JSON: {exc}") from None
        if not isinstance(data, dict):
            raise EvtmsInputError(f"LUT attribute {attr!r} is not a JSON object of parameters")
        if attr == "environment":
            data = {"environment": data}
        try:
            params = apply_tables(data, params, sections)
        except EvtmsInputError as exc:
            raise EvtmsInputError(f"LUT attribute {attr!r}: {exc}") from None
    return params
