"""Stage progress: a Prefect progress artifact inside a task run, and every report to in-process listeners."""

from multithumbs.progress import add_listener, remove_listener
from tasks.progress import stage_progress


def test_listeners_hear_every_report_outside_a_run():
    heard = []

    def listen(*report):
        heard.append(report)

    add_listener(listen)
    try:
        progress = stage_progress("perception", 10)
        progress("blazepose shot 1/2", 4, 4)
        progress("appearance", 3, 10)
    finally:
        remove_listener(listen)
    assert heard[-2:] == [("blazepose shot 1/2", 4, 4), ("appearance", 3, 10)]


def test_a_task_gets_a_progress_artifact_of_the_counted_labels(prefect):
    import asyncio

    from prefect import flow, task
    from prefect.client.orchestration import get_client
    from prefect.client.schemas.filters import ArtifactFilter, ArtifactFilterType

    @task
    def perceive() -> None:
        progress = stage_progress("perception: blazepose on 10 frames", 10, lambda label: label.startswith("blaze"))
        progress("blazepose shot 1/2", 4, 4)
        progress("blazepose shot 2/2", 6, 6)
        progress("appearance", 10, 10)  # not counted: the artifact stays at 100, not 200

    @flow
    def run() -> None:
        perceive()

    run()

    async def latest():
        async with get_client() as client:
            found = await client.read_artifacts(artifact_filter=ArtifactFilter(type=ArtifactFilterType(any_=["progress"])))
            return [a for a in found if a.description == "perception: blazepose on 10 frames"]

    artifacts = asyncio.run(latest())
    assert artifacts and float(artifacts[-1].data) == 100.0
