"""`--views`: which views of each trajectory are used, and under which names, whatever layout read them.

`a,b` keeps views `a` and `b` in that order; `src=name` keeps view `src` and calls it `name`. Frames
are lazy, so choosing views after a layout read them costs nothing. A name that is not there is a
DataError listing the views that are, or, for a view the layout did not read (a depth topic), saying why.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

from robofailring.data.model import Frame, Trajectory
from robofailring.errors import DataError, SettingError


@dataclass(frozen=True)
class ViewSelection:
    """The views to keep, as (view as the layout names it, name it gets), in order."""

    picks: tuple[tuple[str, str], ...]

    @classmethod
    def parse(cls, text: str) -> ViewSelection:
        """`a,b` or `src=name,...`; an empty item or a name given twice is a SettingError."""
        picks: list[tuple[str, str]] = []
        for item in text.split(","):
            source, _, name = item.strip().partition("=")
            source, name = source.strip(), (name.strip() or source.strip())
            if not source:
                raise SettingError(f"--views {text!r}: an empty view name (write `a,b` or `src=name,…`)")
            picks.append((source, name))
        names = [name for _, name in picks]
        twice = sorted({name for name in names if names.count(name) > 1})
        if twice:
            raise SettingError(f"--views {text!r}: view name {twice[0]!r} is given twice")
        return cls(picks=tuple(picks))

    def apply(self, trajectory: Trajectory, *, where: str) -> Trajectory:
        """The trajectory with only the chosen views, renamed; a missing view names those there are."""
        views: dict[str, Sequence[Frame]] = {}
        for source, name in self.picks:
            unread = next((s for s in trajectory.skipped if s.view == source), None)
            if source not in trajectory.views and unread is not None:
                raise DataError(
                    f"--views: view {source!r} of trajectory {trajectory.key} of {where} is not read: "
                    f"{unread.reason}; its views are: {', '.join(trajectory.views) or 'none'}"
                )
            if source not in trajectory.views:
                raise DataError(
                    f"--views: no view {source!r} in trajectory {trajectory.key} of {where}; "
                    f"its views are: {', '.join(trajectory.views) or 'none'}"
                )
            views[name] = trajectory.views[source]
        return replace(trajectory, views=views)


def select_views(trajectories: Sequence[Trajectory], views: str | None, *, where: str) -> list[Trajectory]:
    """Each trajectory with the views `--views` chooses (all of them when `views` is None)."""
    if views is None:
        return list(trajectories)
    selection = ViewSelection.parse(views)
    return [selection.apply(trajectory, where=where) for trajectory in trajectories]
