"""dronefly-fmu: FMI co-simulation of the lateral stabilization control of a hovering model insect."""

__version__ = "0.1.0"
__all__ = ["__version__"]
