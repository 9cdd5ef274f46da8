"""Stone Soup YAML (``stonesoup.serialise.YAML``) for the bridge's types.

The bridge's own classes are Stone Soup ``Base`` classes, which Stone Soup's YAML already
writes. Reading them back needs a constructor for their ``!sensorplan.`` tags (Stone Soup's
covers ``!stonesoup.`` only), and the radar's :class:`~sensorplan.models.sensors.SensorParams` (a
core dataclass) needs a representer and a constructor. :func:`yaml_init` registers these with
a YAML instance; importing the bridge registers them with ruamel's representer and
constructor classes, so ``YAML().dumps(...)`` and ``YAML().load(...)`` work in any process
that has imported ``sensorplan.integrations.stonesoup``.
"""

from __future__ import annotations

import dataclasses
from collections import OrderedDict
from typing import Any

import numpy as np
import ruamel.yaml.constructor as ruamel_constructor
import ruamel.yaml.representer as ruamel_representer
from ruamel.yaml.constructor import ConstructorError
from ruamel.yaml.representer import RepresenterError
from stonesoup.base import Base
from stonesoup.serialise import get_class, yaml_tag

from ...models.sensors import SensorParams

_PARAMS_TAG = yaml_tag(SensorParams)
_PREFIX = "!sensorplan."


def _params_to_yaml(representer: Any, params: SensorParams) -> Any:
    """A ``SensorParams`` as a mapping of the fields that differ from their defaults."""
    values = OrderedDict()
    for f in dataclasses.fields(params):
        value = getattr(params, f.name)
        if value != f.default:
            values[f.name] = list(value) if isinstance(value, tuple) else value
    return representer.represent_omap(_PARAMS_TAG, values)


def _params_from_yaml(constructor: Any, node: Any) -> SensorParams:
    constructor.deep_construct = True
    (values,) = list(constructor.construct_yaml_omap(node))
    kwargs: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v
                              for k, v in values.items()}
    try:
        return SensorParams(**kwargs)
    except TypeError as e:
        raise ConstructorError("while constructing SensorParams", node.start_mark, str(e),
                               node.start_mark) from None


def _declarative_from_yaml(constructor: Any, tag_suffix: str, node: Any) -> Any:
    """A bridge class (a Stone Soup ``Base``) from its ``!sensorplan.`` mapping, as Stone Soup
    builds its own classes."""
    tag = _PREFIX + tag_suffix
    try:
        cls = get_class(tag)
    except (ImportError, AttributeError):
        cls = None
    if not (isinstance(cls, type) and issubclass(cls, Base)):
        raise ConstructorError("while constructing a sensorplan component", node.start_mark,
                               f"{tag!r} is not a sensorplan Stone Soup component",
                               node.start_mark)
    constructor.deep_construct = True        # mutable sub-objects must be complete
    (values,) = list(constructor.construct_yaml_omap(node))
    try:
        return cls(**values)
    except (TypeError, ValueError, AttributeError) as e:
        raise ConstructorError("while constructing a sensorplan component", node.start_mark,
                               str(e), node.start_mark) from None


def _generator_to_yaml(representer: Any, gen: Any) -> Any:
    raise RepresenterError(f"cannot save a numpy Generator ({gen!r}) as YAML; give "
                           "SensorplanManager an integer seed instead (rng=<int>)")


def yaml_init(yaml: Any) -> None:
    """Register the bridge's YAML representer and constructors with a ruamel ``YAML``
    instance (the signature of Stone Soup's ``stonesoup.serialise.yaml`` entry point)."""
    yaml.representer.add_representer(SensorParams, _params_to_yaml)
    yaml.representer.add_representer(np.random.Generator, _generator_to_yaml)
    yaml.constructor.add_constructor(_PARAMS_TAG, _params_from_yaml)
    yaml.constructor.add_multi_constructor(_PREFIX, _declarative_from_yaml)


def _register_globally() -> None:
    """ruamel keeps representers and constructors per class: register with the classes of
    every YAML type Stone Soup's ``YAML`` can use (round trip by default, safe, unsafe)."""
    for name in ("RoundTripRepresenter", "SafeRepresenter", "Representer"):
        cls = getattr(ruamel_representer, name, None)
        if cls is not None:
            cls.add_representer(SensorParams, _params_to_yaml)
            cls.add_representer(np.random.Generator, _generator_to_yaml)
    for name in ("RoundTripConstructor", "SafeConstructor", "Constructor"):
        cls = getattr(ruamel_constructor, name, None)
        if cls is not None:
            cls.add_constructor(_PARAMS_TAG, _params_from_yaml)
            cls.add_multi_constructor(_PREFIX, _declarative_from_yaml)


_register_globally()
