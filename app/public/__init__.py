"""The public functions: the command line's commands as Python (what ``import handeye`` gives),
simulate and plan, the report's command, and the argument checks they share.
"""
