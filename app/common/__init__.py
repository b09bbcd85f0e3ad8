"""What every room of the application uses, with no numpy behind most of it: the errors of bad
requests, the option names and every command's option table (the parser, the public functions'
keywords, provenance and the README's tables are made from it), the argument checks the tables
name, atomic files with provenance, strict JSON, and the studies' names.
"""
