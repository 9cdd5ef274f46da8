"""The run-setting options of ``sensorplan simulate`` and ``agents`` and the link and agent
options of ``agents``, generated from the declarations of the settings
(:mod:`sensorplan.simulation.settings`) and of the decentralized planners' own
(:mod:`sensorplan.decentral.params`), and how every command's ``--help`` is laid out.

``--help`` is meant to be read at 80 columns: options are grouped in panels (one per
settings section, plus the commands' own), each says in a few words what it sets, and
docs/cli.md gives the details of every option. A flag shows no value placeholder: it
takes none.
"""

from __future__ import annotations

import inspect
from typing import Annotated, Any

import typer

from ..decentral.params import agent_params
from ..simulation.settings import all_settings, cli_type, default_of, field_type

#: The ``--help`` panel of each settings section, and of the commands' own options.
PANELS = {"planning": "Planning", "tracker": "Tracking", "run": "Run"}
OUTPUT_PANEL = "Output"
AGENTS_PANEL = "Agents and links"


def setting_options(skip: tuple[str, ...] = ()) -> list[inspect.Parameter]:
    """An option of ``simulate`` for every run setting that declares option names (but those
    in ``skip``), with its brief help, value placeholder, default and panel from the
    declaration (sensorplan.simulation.settings)."""
    params = []
    for cls, _, f, s in all_settings():
        if not s.cli or f.name in skip:
            continue
        text = (s.brief or s.help).removesuffix(".")
        # Choices known only at run time (or open lists) cannot be written into the brief.
        if callable(s.choices):
            text += f" ({', '.join(s.allowed())})"
        elif s.names is not None:
            text += f" ({', '.join(s.names())}, ...)"
        flag = field_type(cls, f.name) is bool
        default = default_of(f)
        if flag:                            # the flag that is on by default: "--gate"
            on, _, off = s.cli[0].partition("/")
            default = on if default else off
        option = typer.Option(*s.cli, metavar="" if flag else s.metavar, show_default=False,
                              rich_help_panel=PANELS[s.section],
                              help=f"{text}. [default: {default}]")
        params.append(inspect.Parameter(f.name, inspect.Parameter.KEYWORD_ONLY, default=None,
                                        annotation=Annotated[cli_type(cls, f.name) | None,
                                                             option]))
    return params


def agent_option(key: str) -> Any:
    """The ``sensorplan agents`` option of the decentralized planners' setting ``key``: its
    names, placeholder, brief help with its range, and default, from the setting's
    declaration (sensorplan.decentral.params)."""
    f, p = agent_params()[key]
    rule = p.bounds.text() if p.bounds is not None else ""   # choices: in the brief
    default = f.default
    shown = f"{default:g}" if isinstance(default, float) else str(default)
    text = (p.brief or p.help).removesuffix(".") + (f", {rule}" if rule else "")
    return typer.Option(*p.cli, metavar=p.metavar, show_default=False,
                        rich_help_panel=AGENTS_PANEL, help=f"{text}. [default: {shown}]")


def agent_option_names() -> dict[str, str]:
    """Setting -> the ``sensorplan agents`` option that sets it (errors name the option)."""
    return {key: p.cli[0] for key, (_, p) in agent_params().items()}


def with_setting_options(command: Any, skip: tuple[str, ...] = ()) -> Any:
    """``command`` with an option per run setting (but those in ``skip``) after its first
    two parameters (typer reads a command's options from its signature and calls it with
    keywords only)."""
    fixed = [p.replace(kind=inspect.Parameter.KEYWORD_ONLY)
             for p in inspect.signature(command, eval_str=True).parameters.values()
             if p.kind is not inspect.Parameter.VAR_KEYWORD]
    command.__signature__ = inspect.Signature(fixed[:2] + setting_options(skip) + fixed[2:])
    return command


def no_flag_placeholders(command: Any) -> Any:
    """``command`` (a click group) with no value placeholder shown for any flag of it or of
    its subcommands, ``--help`` included: typer shows ``<bool>`` for a flag, which reads as
    if it took a value (``--gate false`` would then name a scenario file ``false``)."""
    for cmd in [command, *getattr(command, "commands", {}).values()]:
        ctx = typer.Context(cmd, info_name=cmd.name,
                            help_option_names=["-h", "--help"])   # as the app's settings
        # The help option is made on first use; make it now, so that it can be changed.
        params = [*cmd.params, cmd.get_help_option(ctx)]
        for param in params:
            if param is not None and getattr(param, "is_flag", False):
                param.metavar = ""
    return command
