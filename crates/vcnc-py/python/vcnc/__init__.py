"""vcnc from Python: traces, identification, models and machine runs, numpy in and out.

See docs/python.md. Every function calls what the command line calls, so the results are the
command line's bit for bit; bad input raises ValueError with the command line's message.
"""

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
