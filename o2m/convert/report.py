"""The conversion report: what was converted, approximated (with its measured error) or skipped.

A conversion writes it beside the MJCF as ``<stem>.report.json`` and ``<stem>.report.txt``.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

from o2m.convert.records import Approximation, JointRecord
from o2m.convert.wrapfit import PathFit, format_fits
from o2m.osim.skeleton import Skipped

__all__ = ["ConversionReport"]


@dataclass
class ConversionReport:
    """What a conversion did: every element converted, approximated (with its error) or skipped."""

    model: str
    source: str
    source_version: int
    xml: str
    seconds: float
    counts: dict[str, int]
    joints: list[JointRecord] = field(default_factory=list)
    approximations: list[Approximation] = field(default_factory=list)
    skipped: list[Skipped] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    #: One :class:`o2m.wrapfit.PathFit` (as a dict) per tendon whose wrap geoms were fitted.
    path_fits: list[dict] = field(default_factory=list)
    #: Seconds spent fitting wrap geoms (part of ``seconds``).
    path_fit_seconds: float = 0.0
    #: The ``path_forces`` option, and one :class:`o2m.tendons.PathForceRecord` (as a dict) per
    #: path with same-body MovingPathPoint segments: which tendon it got and what that implies.
    path_forces_mode: str = "auto"
    path_forces: list[dict] = field(default_factory=list)
    #: One :class:`o2m.lengthvia.LengthVia` (as a dict) per segment given a designed length.
    length_vias: list[dict] = field(default_factory=list)

    def to_dict(self) -> dict:
        return asdict(self)

    def summary(self, timing: bool = True) -> str:
        """A readable account of the conversion (what the .report.txt file holds); ``timing``:
        with the conversion time (off where the text must not change from run to run)."""
        lines = [f"o2m conversion report: {self.model}",
                 f"  source   {self.source} (OpenSim document version {self.source_version})",
                 f"  output   {self.xml}",
                 *([f"  time     {self.seconds:.2f} s"] if timing else []),
                 "  converted: " + ", ".join(f"{v} {k}" for k, v in self.counts.items())]
        lines.append("")
        lines.append("MuJoCo joints:")
        for j in self.joints:
            via = f" <- {j.driven_by}" if j.driven_by else ""
            lines.append(f"  {j.name:32s} {j.kind:5s} {j.opensim_joint}/{j.axis:12s} {j.relation}{via}")
        lines.extend(f"  note: {n}" for n in self.notes)
        lines.append("")
        lines.append(f"Approximations ({len(self.approximations)}):")
        for a in self.approximations:
            lines.append(f"  <{a.element} {a.name}> {a.what}: worst error {a.max_error:.3g} {a.units}"
                         + (f" ({a.detail})" if a.detail else ""))
        if not self.approximations:
            lines.append("  none: the MuJoCo kinematics are exact")
        lines.append("")
        lines.append(f"Skipped ({len(self.skipped)}):")
        by_reason: dict[str, list[str]] = {}
        for s in self.skipped:
            by_reason.setdefault(s.reason, []).append(f"{s.element} {s.name}".strip())
        for reason, items in by_reason.items():
            shown = ", ".join(items[:8]) + (f", ... ({len(items)} in all)" if len(items) > 8 else "")
            lines.append(f"  {reason}: {shown}")
        if self.path_forces:
            lines.append("")
            lines.append(f"Path forces ({self.path_forces_mode}; same-body MovingPathPoint segments, along which "
                         f"OpenSim applies no tension):")
            for r in self.path_forces:
                arms = ", ".join(f"{c} {v:.3g}" for c, v in r["moment_arm_mm"].items())
                lines.append(f"  {r['path']:12s} {r['mode']:9s} segments vary {r['variation_mm']:.3g} mm "
                             f"({r['variation_pct']:.3g} % of {r['shortest_mm']:.4g} mm); length error "
                             f"{r['length_error_mm']:.3g} mm ({r['length_error_pct']:.3g} %); computeMomentArm - "
                             f"(-dL/dq) up to [mm] {arms}")
        if self.path_fits:
            fits = [PathFit(**f) for f in self.path_fits]
            lines.append("")
            lines.append(f"Wrap fits ({len(fits)} tendons, {sum(f.accepted for f in fits)} improved, "
                         f"{self.path_fit_seconds:.1f} s; OpenSim -dL/dq over {fits[0].poses} poses):")
            lines.extend(format_fits(fits))
        if self.warnings:
            lines.append("")
            lines.append("Warnings:")
            lines.extend(f"  {w}" for w in self.warnings)
        return "\n".join(lines) + "\n"

    def write(self, folder: Path, stem: str) -> None:
        (folder / f"{stem}.report.json").write_text(json.dumps(self.to_dict(), indent=1, default=float))
        (folder / f"{stem}.report.txt").write_text(self.summary())
