"""Stubs of the vcnc package: the names of vcnc._vcnc (see _vcnc.pyi)."""

from ._vcnc import (
    Channel,
    Identification,
    Kinematics,
    Machine,
    Model,
    PairedAxis,
    Trace,
    __version__,
    identify,
    identify_trace,
    load_models,
    models_toml,
    read_trace,
)

__all__ = [
    "Channel",
    "Identification",
    "Kinematics",
    "Machine",
    "Model",
    "PairedAxis",
    "Trace",
    "__version__",
    "identify",
    "identify_trace",
    "load_models",
    "models_toml",
    "read_trace",
]
