"""Ground floor: what every floor uses (the exception base, atomic result files, Ctrl-C between steps, optional packages). Imports nothing of the project."""
