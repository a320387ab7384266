"""Do-nothing controller with StateFeedback's interface: the floor of the FMI call cost."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class NullController(Fmi2Slave):
    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        for name in ("delta_v", "delta_p", "delta_r", "delta_gamma"):
            setattr(self, name, 0.0)
            self.register_variable(Real(name, causality=Fmi2Causality.input))
        for name in ("delta_Phi_a", "delta_alpha_1a", "delta_alpha_2a"):
            setattr(self, name, 0.0)
            self.register_variable(Real(name, causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        return True
