"""The tracer's ground floor: errors, 3-vectors as rows, the settings table, the version, where the tracer lives, malloc settings. Imports nothing of the tracer."""
