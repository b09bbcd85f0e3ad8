"""handeye's studies: each tells one story (model, data, solve, report) and asserts its claims."""
