"""The ``handeye`` command line: the parser of every subcommand's options (standard library only, so
``handeye --help`` never loads numpy) and the handlers, signals and exit codes.
"""
