"""The ``handeye`` command line's arguments, made from the option tables of
:mod:`handeye.app.common.options` (one subcommand per table, one argument per option), and the parser
that turns an argparse error into one line (exit 2; with ``--json`` its JSON object too).

Imports only the standard library and the names of the options (:mod:`handeye.app.common.choices`,
:mod:`handeye.model.chain.names`), so that ``handeye --help`` never loads numpy
(:mod:`handeye.app.command.cli` runs the commands).
"""
from __future__ import annotations

import argparse
import sys

EXIT_BAD_INPUT = 2


def dumps(data):
    """JSON text of a result (:func:`handeye.app.present.results.dumps`, imported when needed)."""
    from handeye.app.present.results import dumps as to_json

    return to_json(data)


class Parser(argparse.ArgumentParser):
    """argparse's parser with the one-line error below, and without abbreviations: ``--unknown sensor+sphere`` once
    passed as ``--unknowns`` silently (an option is named in full, or refused naming itself)."""

    def __init__(self, *args, **keywords):
        super().__init__(*args, allow_abbrev=False, **keywords)

    def error(self, message):
        """The one line that matters and where to read more; no usage block (exit 2)."""
        if message.endswith("expected one argument"):  # `--sensor-pose -1750,...`: the value read as an option
            message += " (a value that starts with '-' is written --option=VALUE, e.g. --sensor-pose=-1750,...)"
        if message.endswith("required: OUT"):  # `dataset new --profiles a.yml b.yml OUT`: OUT read as a profile
            message += " (--profiles takes every word up to the next option: give OUT first)"
        sys.stderr.write(f"{self.prog}: error: {message}\nsee `{self.prog} --help`\n")
        if json_wanted:  # the JSON of every exit: this one's too
            sys.stdout.write(dumps({"error": f"{self.prog}: {message}", "exit_code": EXIT_BAD_INPUT}) + "\n")
        raise SystemExit(EXIT_BAD_INPUT)


#: Set by :func:`handeye.app.command.cli.main`: ``--json`` among the arguments (an argparse error prints its
#: JSON object too).
json_wanted = False


def build_parser(commands=None):
    """The ``handeye`` parser: one subcommand per table of ``commands`` (default
    :data:`handeye.app.common.options.COMMANDS`), one argument per option."""
    from handeye.app.common.options import COMMANDS, GROUPS

    parser = Parser(prog="handeye", description="Hand-eye calibration workbench (laser-line sensor, sphere).")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    groups = {}
    for name, command in (commands or COMMANDS).items():
        group, _, action = name.partition(" ")
        if action and group not in groups:
            groups[group] = sub.add_parser(group, help=GROUPS[group]).add_subparsers(
                dest="action", required=True, parser_class=Parser)
        add = groups[group].add_parser if action else sub.add_parser
        command_parser = add(action or name, help=command.help)
        for opt in command.options:
            flags, keywords = opt.argument()
            command_parser.add_argument(*flags, **keywords)
    return parser
