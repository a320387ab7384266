"""Floor 3, the plant FMUs: one folder per FMU (slave, README with the equations, reference results)."""
