"""Signal source for tests and demos: sine, seeded noise, or rows of a CSV file at a fixed rate,
as ``Array`` messages or as ``JointState`` (the values as joint positions)."""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import Field

from handflow.framework.files.inputs import InputPath
from handflow.framework.files.params import StrictModel
from handflow.framework.messages import Array, JointState, Message
from handflow.framework.plugin import Node


class SignalParams(StrictModel):
    kind: Literal["sine", "noise", "csv"] = "sine"
    rate_hz: float = Field(100.0, gt=0)
    width: int = Field(1, ge=1, description="values per message (sine/noise)")
    frequency_hz: float = Field(1.0, description="sine frequency; channel k is phase-shifted by k/width of a period")
    amplitude: float = 1.0
    seed: int = 0
    csv: (
        Annotated[str, InputPath(what="CSV file", hint="fix the path (relative to the graph file's folder)")] | None
    ) = Field(None, description="CSV file with a header row (kind: csv); one row per message")
    loop: bool = Field(True, description="restart the CSV at its end")
    message: Literal["array", "joint_state"] = Field(
        "array",
        description="publish Array, or JointState with the values as positions (names: the CSV header or j0, j1, …)",
    )


class SignalSource(Node):
    """Publishes a sine, seeded noise or CSV rows as Array (or JointState) messages at rate_hz."""

    Params = SignalParams
    outputs = {"out": Array}

    @classmethod
    def output_types(cls, params: SignalParams) -> dict[str, type[Message]]:
        return {"out": JointState if params.message == "joint_state" else Array}

    def setup(self) -> None:
        p = self.params
        self.count = 0
        self.rng = np.random.default_rng(p.seed)
        self.names: list[str] = []
        if p.kind == "csv":
            if not p.csv:
                raise ValueError("kind 'csv' needs the param 'csv' (path to a CSV file with a header row)")
            path = self.ctx.resolve_path(p.csv)
            self.names = path.read_text().splitlines()[0].split(",")
            try:
                self.rows = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
            except ValueError as exc:
                raise ValueError(f"{path}: not numeric CSV rows under a header row ({exc}); fix the file") from None
            if not np.isfinite(self.rows).all():
                raise ValueError(f"{path} holds NaN/inf values; clean the file")
        self.joint_names = self.names or [f"j{k}" for k in range(p.width)]  # message: joint_state

    def tick(self) -> None:
        p = self.params
        if p.kind == "sine":
            t = self.count / p.rate_hz
            data = p.amplitude * np.sin(2 * np.pi * (p.frequency_hz * t + np.arange(p.width) / p.width))
        elif p.kind == "noise":
            data = p.amplitude * self.rng.standard_normal(p.width)
        else:
            if self.count >= len(self.rows) and not p.loop:
                return
            data = self.rows[self.count % len(self.rows)]
        self.count += 1
        if p.message == "joint_state":
            self.ctx.publish(
                "out", JointState(names=list(self.joint_names), positions=np.asarray(data, dtype=np.float64))
            )
        else:
            self.ctx.publish("out", Array(data=data, names=list(self.names)))
