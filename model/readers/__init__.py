"""A dataset's files read and checked: CSV tables, numbers, ids and pose lists in any robot convention,
and setup.toml with the mounts it states.
"""
