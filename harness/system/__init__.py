"""Systems of any number of FMI 2.0 co-simulation FMUs.

- :mod:`.description`: :class:`System` (instances, connections, parameter values), from
  Python, an SSP file or connect-by-name;
- :mod:`.graph`: direct feedthrough from each FMU's ModelStructure, the Gauss-Seidel order,
  algebraic loops, type and unit checks of connections;
- :mod:`.master`: :class:`SystemMaster`, the fixed-step master (Gauss-Seidel or Jacobi).
"""
