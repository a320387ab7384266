"""Top floor, beside the CLI: build the FMUs, their model descriptions and the systems of FMUs."""
