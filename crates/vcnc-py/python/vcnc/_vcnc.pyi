"""Type stubs of the extension module vcnc._vcnc (crates/vcnc-py/src)."""

import os
from typing import Any, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

__version__: str

ArrayLike = npt.ArrayLike
F64 = npt.NDArray[np.float64]
PathLike = Union[str, "os.PathLike[str]"]

class Channel:
    name: str
    description: str
    axis: Optional[str]
    quantity: str
    unit: Optional[str]
    period_s: Optional[float]
    t0_s: float
    line: int
    column: int
    samples: F64

class PairedAxis:
    axis: str
    unit: str
    ts_s: float
    t0_s: float
    t: F64
    nominal: F64
    actual: F64
    nominal_channel: str
    actual_channel: str

class Trace:
    @property
    def file(self) -> str: ...
    @property
    def format(self) -> str: ...
    @property
    def metadata(self) -> list[tuple[str, str]]: ...
    @property
    def channels(self) -> list[Channel]: ...
    def pair(self) -> list[PairedAxis]: ...

def read_trace(
    path: PathLike,
    *,
    ts: Optional[float] = None,
    units: Optional[str] = None,
    trace_format: Optional[str] = None,
    joints: Optional[str] = None,
    axis_map: Optional[str] = None,
    t_col: Optional[str] = None,
    axes: Optional[Sequence[str]] = None,
    xr_col: Optional[str] = None,
    x_col: Optional[str] = None,
    gaps: Optional[str] = None,
) -> Trace: ...

class Model:
    @staticmethod
    def from_toml(path: PathLike, axis: Optional[str] = None) -> Model: ...
    @property
    def axis(self) -> str: ...
    @property
    def unit(self) -> str: ...
    @property
    def structure(self) -> str: ...
    @property
    def parameters(self) -> dict[str, Any]: ...
    @property
    def summary(self) -> dict[str, Any]: ...
    @property
    def dc(self) -> float: ...
    @property
    def delay_s(self) -> float: ...
    @property
    def actual_latency_s(self) -> float: ...
    @property
    def poles(self) -> Optional[dict[str, float]]: ...
    def simulate(self, xr: ArrayLike, ts: float) -> F64: ...
    def frf(self, f_hz: ArrayLike) -> npt.NDArray[np.complex128]: ...
    def validate(
        self,
        t: Union[ArrayLike, float],
        xr: ArrayLike,
        x: ArrayLike,
        *,
        units: Optional[str] = None,
        name: str = "<arrays>",
    ) -> dict[str, Any]: ...
    def to_toml(self, machine: str = "python", description: Optional[str] = None) -> str: ...

def load_models(path: PathLike) -> list[Model]: ...

class Identification:
    @property
    def axis(self) -> str: ...
    @property
    def unit(self) -> str: ...
    @property
    def structure(self) -> str: ...
    @property
    def model(self) -> Model: ...
    @property
    def summary(self) -> dict[str, Any]: ...
    @property
    def structures(self) -> list[dict[str, Any]]: ...
    @property
    def uncertainty(self) -> Optional[list[dict[str, Any]]]: ...
    @property
    def fit(self) -> dict[str, Any]: ...
    @property
    def warnings(self) -> list[str]: ...
    @property
    def validation(self) -> dict[str, F64]: ...
    def to_toml(self) -> str: ...

def identify(
    t: Union[ArrayLike, float],
    xr: ArrayLike,
    x: ArrayLike,
    *,
    units: str = "mm",
    structures: Optional[Sequence[str]] = None,
    options: Optional[str] = None,
    seed: Optional[int] = None,
    axis: str = "X",
    actual_latency_s: Optional[float] = None,
    name: str = "<arrays>",
) -> Identification: ...
def identify_trace(
    path: PathLike,
    *,
    ts: Optional[float] = None,
    units: Optional[str] = None,
    trace_format: Optional[str] = None,
    joints: Optional[str] = None,
    axis_map: Optional[str] = None,
    t_col: Optional[str] = None,
    axes: Optional[Sequence[str]] = None,
    xr_col: Optional[str] = None,
    x_col: Optional[str] = None,
    gaps: Optional[str] = None,
    structures: Optional[Sequence[str]] = None,
    options: Optional[str] = None,
    seed: Optional[int] = None,
    actual_latency_s: Optional[float] = None,
) -> list[Identification]: ...
def models_toml(
    identifications: Sequence[Identification],
    *,
    machine: Optional[str] = None,
    description: Optional[str] = None,
) -> str: ...

class Kinematics:
    @property
    def axis_names(self) -> list[str]: ...
    def forward(self, axes: ArrayLike) -> F64: ...
    def inverse(self, poses: ArrayLike, branch: Optional[int] = None) -> F64: ...

Run = tuple[dict[str, F64], dict[str, Any]]

class Machine:
    def __init__(self, path: PathLike) -> None: ...
    @property
    def name(self) -> str: ...
    @property
    def axes(self) -> list[str]: ...
    @property
    def kinematics(self) -> Kinematics: ...
    def interpolate(self, program: PathLike, *, lenient: bool = False) -> Run: ...
    def simulate(
        self, program: PathLike, models: Optional[PathLike] = None, *, lenient: bool = False
    ) -> Run: ...
    def predict(
        self,
        program: PathLike,
        models: Optional[PathLike] = None,
        *,
        include_rapids: bool = False,
        lenient: bool = False,
    ) -> Run: ...
