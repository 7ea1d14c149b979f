"""The seed paper's test plan on the virtual rig, written as physical campaigns.

Seed section 5: for each bolt preload (120 and 540 N) a low-level random test (linear
FRFs, Fig 9, Table 4) and stepped sine around the first mode at F = 1.5, 3 and 6 N
(Fig 10).  :func:`run_test_plan` simulates one preload and writes a campaign folder in
the contract format of :mod:`jointid.io.campaign`::

    <folder>/campaign.toml          coordinates = "physical", [structure], one [[record]] per dwell
    <folder>/records/F1.5_000.csv   time, force, accel_30, accel_42 (full double precision)
    <folder>/records/F1.5_000.uff   the same record as UFF dataset 58 (binary 58b, bit-exact)
    <folder>/random/random.uff      the random test (and .csv when asked for)
    <folder>/ringdown/R6.uff        free decay released at 6 N (``excitation = "ringdown"``), when planned

One campaign per preload: the ``[structure]`` of a campaign is one structure, and the
updated beam differs between the preloads.  The manifest names the UFF files (the
measured-data path) or the CSV files (``MeasurementPlan.manifest_format``).

The ``[structure]`` section written first is the as-built description (seed beam,
sensor and shaker positions, nominal joint); :func:`structure_section` builds the one
with the joint and clamp stiffnesses updated from the random test, which the demo writes
back into the manifest before identification.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import StructureError
from ..io.campaign import load_campaign, write_campaign, write_csv_record
from ..io.channels import Channels
from ..io.uff import read_uff, write_uff
from .rig import Acquisition, RandomTest, VirtualRig

__all__ = ["MeasurementPlan", "RigCampaign", "run_test_plan", "structure_section", "write_manifest", "read_random_record"]


@dataclass(frozen=True)
class MeasurementPlan:
    """What the rig measures at one preload.

    Parameters
    ----------
    force_levels : tuple of float
        Stepped-sine force amplitudes [N] (seed: 1.5, 3, 6).
    band : (float, float)
        Stepped-sine band as fractions of the rig's linear first frequency.
    n_frequencies : int
        Dwells per force level.
    acquisition : Acquisition
    random : RandomTest
    formats : tuple of {"csv", "uff"}
        Files written for every stepped-sine record.
    manifest_format : {"uff", "csv"}
        Which of them the manifest names.
    random_formats : tuple of {"csv", "uff"}
        Files written for the random record.
    ringdown_levels : tuple of float
        Shaker force amplitudes [N] at which mode 1 is driven in phase resonance and
        released (one ring-down record each, ``excitation = "ringdown"``); empty: none.
    ringdown_duration : float
        Length of each ring-down record after the release [s].
    """

    force_levels: tuple = (1.5, 3.0, 6.0)
    band: tuple = (0.982, 1.010)
    n_frequencies: int = 21
    acquisition: Acquisition = field(default_factory=Acquisition)
    random: RandomTest = field(default_factory=RandomTest)
    formats: tuple = ("csv", "uff")
    manifest_format: str = "uff"
    random_formats: tuple = ("uff",)
    ringdown_levels: tuple = ()
    ringdown_duration: float = 4.0

    def __post_init__(self):
        if self.manifest_format not in self.formats:
            raise StructureError(f"manifest_format {self.manifest_format!r} must be one of the formats {self.formats}")
        for f in tuple(self.formats) + tuple(self.random_formats):
            if f not in ("csv", "uff"):
                raise StructureError(f"record format: expected 'csv' or 'uff', got {f!r}")
        lo, hi = self.band
        if not 0 < lo < hi:
            raise StructureError(f"band: expected 0 < low < high, got {self.band!r}")
        if int(self.n_frequencies) < 3:
            raise StructureError(f"n_frequencies: expected at least 3, got {self.n_frequencies!r}")

    def frequencies_hz(self, rig: VirtualRig) -> np.ndarray:
        """Dwell frequencies [Hz] (swept upwards)."""
        f1 = float(rig.linear_frequencies_hz[0])
        return f1 * np.linspace(self.band[0], self.band[1], int(self.n_frequencies))

    def summary(self) -> dict:
        return {
            "force_levels": list(self.force_levels),
            "band": list(self.band),
            "n_frequencies": int(self.n_frequencies),
            "acquisition": self.acquisition.summary(),
            "random": self.random.summary(),
            "formats": list(self.formats),
            "manifest_format": self.manifest_format,
            "ringdown_levels": list(self.ringdown_levels),
            "ringdown_duration": float(self.ringdown_duration),
        }


@dataclass(frozen=True, eq=False)
class RigCampaign:
    """A simulated preload written to a campaign folder.

    Attributes
    ----------
    folder : Path
    rig : VirtualRig
    plan : MeasurementPlan
    dwells : tuple of Dwell
    entries : tuple of dict
        Manifest entries (``file`` and keys) with the paths of every format written
        (``files``).
    random_files : dict
        Format -> path (relative to the folder) of the random record.
    random_joint_motion : dict
        ``{"max": [...], "rms": [...]}``: largest and RMS joint motion during the random
        test, per joint law.
    """

    folder: Path
    rig: VirtualRig
    plan: MeasurementPlan
    dwells: tuple
    entries: tuple
    random_files: dict
    random_joint_motion: dict

    @property
    def name(self) -> str:
        return f"virtual rig, preload {self.rig.preload:g} N"

    def records(self, fmt: str | None = None) -> list:
        """Paths of the stepped-sine record files of a format (default: the manifest's)."""
        fmt = fmt or self.plan.manifest_format
        return [self.folder / e["files"][fmt] for e in self.entries]


def _slug(x) -> str:
    return f"{float(x):g}".replace("-", "m")


def as_built_structure(rig: VirtualRig) -> dict:
    """``[structure]`` of the as-built description: seed beam, shaker and sensors, nominal joint."""
    return {
        "model": "seed-bolted-beam",
        "force_position": rig.force_position,
        "force_column": "force",
        "basis_modes": 1,
        "sensors": dict(rig.sensors),
    }


def structure_section(rig: VirtualRig, beam, basis_modes: int = 1) -> dict:
    """``[structure]`` with the joint and clamp stiffnesses of an (updated) beam.

    Parameters
    ----------
    rig : VirtualRig
        For the shaker and sensor positions.
    beam : JointedBeam
        The updated model (``k_w``, ``k_t`` of its spring joint, clamp stiffness).
    basis_modes : int
        Modes in the least-squares basis of the modal coordinates (at most the number
        of accelerometers); 1 is the seed's ``d = phi_1 q``.
    """
    clamp = beam.clamp_stiffness
    return {
        "model": "seed-bolted-beam",
        "force_position": rig.force_position,
        "force_column": "force",
        "basis_modes": int(basis_modes),
        "beam": {"clamp_stiffness": "inf" if math.isinf(clamp) else float(clamp), "n_elements": int(beam.n_elements)},
        "joint": {"k_w": float(beam.joint.k_w), "k_t": float(beam.joint.k_t)},
        "sensors": dict(rig.sensors),
    }


def write_manifest(campaign: RigCampaign, structure: dict, extra: dict | None = None) -> Path:
    """(Re)write ``campaign.toml`` with a ``[structure]`` section."""
    head = {"generator": "jointid virtual rig", "preload": campaign.rig.preload,
            "random_record": campaign.random_files.get(campaign.plan.manifest_format)
            or next(iter(campaign.random_files.values()))}
    head.update(extra or {})
    records = [{k: v for k, v in e.items() if k != "files"} for e in campaign.entries]
    return write_campaign(campaign.folder, campaign.name, records, coordinates="physical", structure=structure,
                          extra=head)


def _write(path: Path, rec: Channels, fmt: str):
    path.parent.mkdir(parents=True, exist_ok=True)
    if fmt == "csv":
        write_csv_record(path, rec.time, dict(rec.data))
    else:
        write_uff(path, rec, binary=True)


def run_test_plan(rig: VirtualRig, plan: MeasurementPlan, folder, *, rng=None, progress=None) -> RigCampaign:
    """Simulate one preload's random and stepped-sine tests and write its campaign folder.

    Parameters
    ----------
    rig : VirtualRig
    plan : MeasurementPlan
    folder : path
        Campaign folder (created).
    rng : seed or numpy Generator
    progress : callable, optional
        Called with a short text after each step (the demo passes a tqdm update).

    Returns
    -------
    RigCampaign
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(rng)
    random_rec = rig.random_test(plan.random, plan.acquisition, rng, source="random")
    random_files = {}
    for fmt in plan.random_formats:
        rel = f"random/random.{fmt}"
        _write(folder / rel, random_rec, fmt)
        random_files[fmt] = rel
    if progress:
        progress("random test")
    dwells, entries = [], []
    freqs = plan.frequencies_hz(rig)
    for F in plan.force_levels:
        ds = rig.stepped_sine(freqs, F, plan.acquisition, rng)
        for i, d in enumerate(ds):
            files = {}
            for fmt in plan.formats:
                rel = f"records/F{_slug(F)}_{i:03d}.{fmt}"
                _write(folder / rel, d.record, fmt)
                files[fmt] = rel
            entries.append({
                "file": files[plan.manifest_format],
                "frequency_hz": float(d.frequency_hz),
                "force_level": float(F),
                "preload": float(rig.preload),
                "settled": bool(d.settled),
                "files": files,
            })
        dwells.extend(ds)
        if progress:
            progress(f"stepped sine F = {F:g} N")
    if plan.ringdown_levels:
        for F, (rec, _) in zip(plan.ringdown_levels, rig.ringdown(plan.ringdown_levels, plan.ringdown_duration,
                                                                  plan.acquisition, rng)):
            files = {}
            for fmt in plan.formats:
                rel = f"ringdown/R{_slug(F)}.{fmt}"
                _write(folder / rel, rec, fmt)
                files[fmt] = rel
            entries.append({"file": files[plan.manifest_format], "force_level": float(F), "preload": float(rig.preload),
                            "excitation": "ringdown", "files": files})
        if progress:
            progress("ring-downs")
    camp = RigCampaign(folder, rig, plan, tuple(dwells), tuple(entries), random_files,
                       {"max": list(random_rec.meta.get("joint_max", [])),
                        "rms": list(random_rec.meta.get("joint_rms", []))})
    write_manifest(camp, as_built_structure(rig))
    return camp


def read_random_record(folder) -> Channels:
    """The random-test record named in a rig campaign's manifest (``[campaign] random_record``)."""
    camp = load_campaign(folder)
    rel = camp.manifest.get("campaign", {}).get("random_record")
    if not rel:
        raise StructureError(f"{Path(folder) / 'campaign.toml'}: no random_record in [campaign]")
    path = Path(folder) / rel
    if path.suffix.lower() == ".csv":
        from ..io.campaign import RecordSpec, read_record

        data = read_record(RecordSpec(-1, rel, path, None, None, None), required=("time", "force"))
        return Channels(data.time, data.channels, source=str(path))
    return read_uff(path)

