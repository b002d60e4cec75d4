"""gcmap: globally consistent 3D LiDAR mapping by global matching-cost minimization.

NumPy in and out; the C++ work runs with the GIL released.

    import gcmap
    config = gcmap.MappingConfig()
    config.preprocess.downsample = 0.5     # sections as attributes; `global` is config.global_
    pipeline = gcmap.MappingPipeline(config, device="auto")
    sim = gcmap.simulate("small", seed=1)
    for i, (points, gt_pose) in enumerate(sim):
        pose, status = pipeline.add_scan(points, stamp=0.1 * i)
    pipeline.finish()
    print(gcmap.eval.ate(sim.poses, pipeline.trajectory))

Functions: read_points, write_points, read_trajectory, write_trajectory, register, simulate, mme.
Classes: MappingConfig, MappingPipeline, RegistrationResult, Simulation. Metrics: gcmap.eval.
Errors: ValueError (bad input, naming the argument, key or file), FileNotFoundError, RuntimeError.
"""
from ._gcmap import (MappingConfig, MappingPipeline, RegistrationResult, Simulation, read_points,
                     read_trajectory, register, simulate, write_points, write_trajectory)
from . import eval
from .eval import mme

__all__ = ["MappingConfig", "MappingPipeline", "RegistrationResult", "Simulation", "eval", "mme",
           "read_points", "read_trajectory", "register", "simulate", "write_points", "write_trajectory"]


class _Section:
    """One section of a MappingConfig; its fields are attributes (changes are validated)."""

    __slots__ = ("_config", "_name")

    def __init__(self, config, name):
        object.__setattr__(self, "_config", config)
        object.__setattr__(self, "_name", name)

    def _key(self, field):
        key = f"{self._name}.{field}"
        if key not in _KEYS:
            raise AttributeError(f"MappingConfig has no key '{key}'")
        return key

    def __getattr__(self, field):
        return self._config.get(self._key(field))

    def __setattr__(self, field, value):
        self._config.set(self._key(field), value)

    def __dir__(self):
        return [k.split(".", 1)[1] for k in MappingConfig.keys() if k.startswith(self._name + ".")]

    def __repr__(self):
        fields = ", ".join(f"{f}={getattr(self, f)!r}" for f in self.__dir__())
        return f"{self._name}({fields})"


def _section_property(name):
    fields = ", ".join(k.split(".", 1)[1] for k in MappingConfig.keys() if k.startswith(name + "."))
    return property(lambda self: _Section(self, name), doc=f"The '{name}' section: {fields}.")


_KEYS = set(MappingConfig.keys())
for _name in dict.fromkeys(k.split(".", 1)[0] for k in MappingConfig.keys()):
    setattr(MappingConfig, _name, _section_property(_name))
MappingConfig.global_ = MappingConfig.__dict__["global"]  # `global` is a Python keyword
del _name
