"""The public functions: the command line's commands as Python (what ``import handeye`` gives),
simulate and plan, and the report's command.
"""
