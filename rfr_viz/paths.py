"""Every Rerun entity path, timeline and property name of a recording (docs/recording.md, "The recording layout"), in one place."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Final, Literal

NeighborPart = Literal["start", "end", "info"]

APPLICATION_ID: Final[str] = "robofailring"
DEFAULT_OUT: Final[Path] = Path("recordings")  # the recordings' folder unless --out names one
FRAME: Final[str] = "frame"  # sequence timeline: frame index t
TIME: Final[str] = "time"  # duration timeline: t / fps seconds
DEFAULT_FPS: Final[float] = 10.0  # when the data source does not say
PROPERTIES: Final[str] = "robofailring"  # recording property group (task, label, outcome, …)
# property: the trajectory is one of the memory's own episodes, scored without leave-one-out (a self-match)
IN_MEMORY: Final[str] = "in_memory"

CAMERA_ROOT: Final[str] = "/camera"
SIGNAL_ROOT: Final[str] = "/signals"


def escape_part(name: str) -> str:
    """`name` as one entity path part: every character but letters, digits, `_`, `-` and `.` escaped with
    a backslash, as Rerun's own `escape_entity_path_part` does (a ROS topic's `/` stays in the part)."""
    return "".join(c if c.isascii() and (c.isalnum() or c in "_-.") else f"\\{c}" for c in name)


def signal(name: str) -> str:
    """`/signals/<name>`: Scalars, one series per dimension of one of the robot's signals (named by it)."""
    return f"{SIGNAL_ROOT}/{escape_part(name)}"


def camera(view: str) -> str:
    """`/camera/<view>`: the JPEG frames of one view (shared by every encoder of a comparison)."""
    return f"{CAMERA_ROOT}/{view}"


@dataclass(frozen=True)
class DetectorPaths:
    """The detector-dependent entities, under `prefix` (`""` for a replay, `/<encoder>` in a comparison)."""

    prefix: str = ""

    @classmethod
    def for_encoder(cls, slug: str) -> DetectorPaths:
        return cls(prefix=f"/{slug}")

    @property
    def score_root(self) -> str:
        return f"{self.prefix}/score"

    def score(self, view: str, rule: str) -> str:
        """Scalars: one scoring rule's score of one view, by the rule's name (`paper`: S⁻_t = S_t, `contrast`:
        C_t = S⁻_t − S⁺_t, `novelty`: N_t = 1 − S⁺_t, and any rule registered beside them)."""
        return f"{self.score_root}/{view}/{rule}"

    def success_score(self, view: str) -> str:
        """Scalars: S⁺_t of one view (max cosine to the task's success frames)."""
        return f"{self.score_root}/{view}/success"

    @property
    def threshold_root(self) -> str:
        return f"{self.score_root}/threshold"

    def threshold(self, rule: str) -> str:
        """Scalars: one scoring rule's threshold line (δ, γ, η, …; μ_t + θ·σ_t with a band), by rule name."""
        return f"{self.threshold_root}/{rule}"

    def view_threshold(self, rule: str, view: str) -> str:
        """Scalars: one rule's threshold line on one view's score where that view is judged by a band of its
        own (the signals' under fusion `per-modality`, each view's under `per-view`), beside the line above."""
        return f"{self.threshold(rule)}/{view}"

    @property
    def nearest_success_root(self) -> str:
        return f"{self.prefix}/nearest_success"

    def nearest_success(self, view: str) -> str:
        """EncodedImage: the success frame nearest to the current query of a view ("normal here")."""
        return f"{self.nearest_success_root}/{view}"

    def nearest_success_info(self, view: str) -> str:
        """TextDocument: its episode, frame index and S⁺."""
        return f"{self.nearest_success(view)}/info"

    @property
    def detection_root(self) -> str:
        return f"{self.prefix}/detection"

    @property
    def state(self) -> str:
        """Scalars: State_t (0/1) fused over views."""
        return f"{self.detection_root}/state"

    @property
    def event(self) -> str:
        """TextLog at the detection instant."""
        return f"{self.detection_root}/event"

    @property
    def neighbors_root(self) -> str:
        return f"{self.prefix}/neighbors"

    def neighbor_rank(self, view: str, rank: int) -> str:
        """The rank-th nearest memory entry of a view (rank 0 is the nearest)."""
        return f"{self.neighbors_root}/{view}/{rank}"

    def neighbor(self, view: str, rank: int, part: NeighborPart) -> str:
        """Its start/end image (EncodedImage) or its info text (TextDocument)."""
        return f"{self.neighbor_rank(view, rank)}/{part}"

    @property
    def map_root(self) -> str:
        """The memory map: one map per view side by side, their AnnotationContext and the legend."""
        return f"{self.prefix}/memory"

    def umap(self, view: str) -> str:
        """Static Points2D of one view's memory entries in that view's map, placed beside the others by a
        static Transform3D."""
        return f"{self.map_root}/umap/{view}"

    def umap_query(self, view: str) -> str:
        """Points2D: the current query of a view projected into that view's map."""
        return f"{self.umap(view)}/query"

    def umap_frame(self, view: str) -> str:
        """Static Boxes2D around one view's map."""
        return f"{self.umap(view)}/frame"

    def umap_title(self, view: str) -> str:
        """Static Points2D: the name of one view's map (and its entry count) at the top of its box."""
        return f"{self.umap(view)}/title"

    @property
    def map_legend(self) -> str:
        """Static Points2D: the failure types of the memory, their colours and counts."""
        return f"{self.map_root}/legend"

    @property
    def report(self) -> str:
        """TextDocument (markdown): failure report and VLM prompt."""
        return f"{self.prefix}/report"


REPLAY: Final[DetectorPaths] = DetectorPaths()


# Closed-loop run (rfr_viz.recordings.closed_loop): the same episode watched (stopped at the alarm) and unstopped.
@dataclass(frozen=True)
class ClosedLoopPaths:
    """The entities of one run: `/<run>/camera/<view>` and the detector's under `/<run>/…`."""

    run: str

    @property
    def root(self) -> str:
        return f"/{self.run}"

    @property
    def detector(self) -> DetectorPaths:
        """S_t, δ, State_t and the alarm event of this run (`/<run>/score/…`, `/<run>/detection/…`)."""
        return DetectorPaths(prefix=self.root)

    def camera(self, view: str) -> str:
        """EncodedImage (JPEG) of every frame the run rendered."""
        return f"{self.root}{camera(view)}"

    def stopped(self, view: str) -> str:
        """A red frame and a "STOPPED" label over the frozen camera image, logged at the stop frame."""
        return f"{self.camera(view)}/stopped"

    @property
    def outcome(self) -> str:
        """TextLog at the run's last frame: the goal check of the scene as it was left."""
        return f"{self.root}/outcome"

    def signal(self, name: str) -> str:
        """Scalars: one of the robot's signals in this run (`/<run>/signals/<name>`)."""
        return f"{self.root}{signal(name)}"


WATCHED: Final[ClosedLoopPaths] = ClosedLoopPaths("watched")  # stopped at the first alarm
UNSTOPPED: Final[ClosedLoopPaths] = ClosedLoopPaths("unstopped")  # scored, never acted on
CLOSED_LOOP_SUMMARY: Final[str] = "/summary"  # static TextDocument (markdown): both runs side by side


# Evaluation summary (rfr_viz.recordings.evaluation).
EVALUATION_APPLICATION_ID: Final[str] = "robofailring-evaluation"
EVAL_ROOT: Final[str] = "/eval"  # /eval/<name>/<chart key>: roc, sweep_<rule>, recall_per_type, …
EVAL_SUMMARY: Final[str] = "/eval/summary"  # TextDocument: the markdown tables


# Triage (rfr_viz.recordings.triage): every episode of a dataset, ranked; one entity per rank.
TRIAGE_ROOT: Final[str] = "/triage"
TRIAGE_RANKING: Final[str] = "/triage/ranking"  # static TextDocument (markdown): the ranked table
TRIAGE_SCORES: Final[str] = "/triage/scores"  # static BarChart: each episode's ranking score, in rank order
TRIAGE_CURVES: Final[str] = "/triage/curves"  # every episode's score curve, one entity each (triage_curve)


def triage_curve(rank: int) -> str:
    """Scalars on the frame timeline: the score curve of the episode ranked `rank` (1: least normal)."""
    return f"{TRIAGE_CURVES}/{rank:04d}"


def triage_episode(rank: int) -> str:
    """The episode ranked `rank`: static `peak` (EncodedImage, its frame at its peak) and `info` (TextDocument)."""
    return f"{TRIAGE_ROOT}/episodes/{rank:04d}"
