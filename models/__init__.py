"""Floor 2, the models: the equations of each axis, the paper's data, the names, units and scales every FMU and analysis agrees on.

The modules an FMU ships use only the Python standard library."""
