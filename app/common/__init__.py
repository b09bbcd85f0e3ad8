"""What every room of the application uses, with no numpy behind most of it: the errors of bad
requests, the option names the command line is built from, atomic files with provenance, and strict
JSON.
"""
