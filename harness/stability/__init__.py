"""``dronefly cosim``: co-simulated closed loops, their neutral-stability verdicts and plots."""
