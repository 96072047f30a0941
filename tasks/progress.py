"""Progress of long stages, to the Prefect UI (a progress artifact) and to whoever listens in-process
(:mod:`multithumbs.progress`: the CLI's bars). A stage calls :func:`stage_progress` once and the callable
it returns as it goes."""

from __future__ import annotations

from typing import Callable

from multithumbs.progress import notify


def stage_progress(description: str, total: int, counts: Callable[[str], bool] = lambda label: True
                   ) -> Callable[[str, int, int], None]:
    """A ``progress(label, done, label_total)`` callable for a stage of ``total`` units (frames): each label
    (e.g. a shot) is a run of units; the Prefect progress artifact shows the share of ``total`` done by the
    labels that ``counts`` (updated per percent), listeners get every report. Outside a Prefect run only
    the listeners are told."""
    artifact = None
    try:
        from prefect.artifacts import create_progress_artifact
        from prefect.context import TaskRunContext

        if TaskRunContext.get() is not None:
            artifact = create_progress_artifact(progress=0.0, description=description)
    except Exception:  # noqa: BLE001 - progress must never fail the stage it reports on
        artifact = None
    finished: dict[str, int] = {}
    shown = [0]

    def progress(label: str, done: int, label_total: int) -> None:
        if counts(label):
            finished[label] = done
        percent = int(100 * sum(finished.values()) / max(total, 1))
        if artifact is not None and percent > shown[0]:
            from prefect.artifacts import update_progress_artifact

            try:
                update_progress_artifact(artifact, float(min(percent, 100)))
                shown[0] = percent
            except Exception:  # noqa: BLE001
                pass
        notify(label, done, label_total)
    return progress
