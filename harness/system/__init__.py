"""Systems of any number of FMI 2.0 co-simulation FMUs.

- :mod:`.description`: :class:`System` (instances, connections, parameter values), from
  Python, an SSP file or connect-by-name;
- :mod:`.graph`: direct feedthrough from each FMU's ModelStructure, the Gauss-Seidel order,
  algebraic loops, type and unit checks of connections;
- :mod:`.values`: parameter and input values converted to their variables' declared types;
- :mod:`.plan`: the buffers and FMI calls of a step, and of the recording;
- :mod:`.master`: :class:`SystemMaster`, the fixed-step master (Gauss-Seidel or Jacobi).
"""
