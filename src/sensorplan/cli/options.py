"""The run-setting options of ``sensorplan simulate`` and ``agents``, generated from the
settings' declarations (:mod:`sensorplan.simulation.settings`)."""

from __future__ import annotations

import inspect
from typing import Annotated, Any

import typer

from ..simulation.settings import all_settings, default_of, field_type


def setting_options(skip: tuple[str, ...] = ()) -> list[inspect.Parameter]:
    """An option of ``simulate`` for every run setting that declares option names (but those
    in ``skip``), with its help, value placeholder and default from the declaration
    (sensorplan.simulation.settings)."""
    params = []
    for cls, _, f, s in all_settings():
        if not s.cli or f.name in skip:
            continue
        # Choices known only at run time cannot be written into the help sentence.
        if callable(s.choices):
            text = s.help.removesuffix(".") + f" ({', '.join(s.allowed())})."
        elif s.names is not None:
            text = s.help.removesuffix(".") + f" ({', '.join(s.names())}, ...)."
        else:
            text = s.help
        option = typer.Option(*s.cli, metavar=s.metavar, show_default=False,
                              help=f"{text} [default: {default_of(f)}]")
        params.append(inspect.Parameter(f.name, inspect.Parameter.KEYWORD_ONLY, default=None,
                                        annotation=Annotated[field_type(cls, f.name) | None,
                                                             option]))
    return params


def with_setting_options(command: Any, skip: tuple[str, ...] = ()) -> Any:
    """``command`` with an option per run setting (but those in ``skip``) after its first
    two parameters (typer reads a command's options from its signature and calls it with
    keywords only)."""
    fixed = [p.replace(kind=inspect.Parameter.KEYWORD_ONLY)
             for p in inspect.signature(command, eval_str=True).parameters.values()
             if p.kind is not inspect.Parameter.VAR_KEYWORD]
    command.__signature__ = inspect.Signature(fixed[:2] + setting_options(skip) + fixed[2:])
    return command
