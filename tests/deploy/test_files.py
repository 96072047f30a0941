"""deploy/ files are consistent with the code: entry points resolve to flows, the job template's
placeholders are all declared, the image pins what scripts/setup.sh pins."""

import importlib
import json
import re
from pathlib import Path

import yaml

DEPLOY = Path(__file__).resolve().parents[2] / "deploy"


def test_every_deployment_entrypoint_is_a_flow_with_those_parameters():
    from prefect import Flow

    deployments = [d for name in ("prefect.yaml", "prefect-gpu.yaml")
                   for d in yaml.safe_load((DEPLOY / name).read_text())["deployments"]]
    assert len(deployments) >= 5
    for deployment in deployments:
        path, name = deployment["entrypoint"].split(":")
        flow = getattr(importlib.import_module(path[:-3].replace("/", ".")), name)
        assert isinstance(flow, Flow), deployment["name"]
        accepted = set(flow.parameters.properties)
        assert set(deployment.get("parameters", {})) <= accepted, deployment["name"]


def test_job_template_declares_every_placeholder():
    template = json.loads((DEPLOY / "k8s" / "gpu-job-template.json").read_text())
    used = set(re.findall(r"\{\{\s*(\w+)\s*\}\}", json.dumps(template["job_configuration"])))
    assert used <= set(template["variables"]["properties"]), used - set(template["variables"]["properties"])
    assert template["variables"]["properties"]["env"]["default"]["HF_HUB_OFFLINE"] == "1"


def test_image_pins_torch_as_setup_does():
    setup = (DEPLOY.parent / "scripts" / "setup.sh").read_text()
    docker = (DEPLOY / "Dockerfile").read_text()
    for pin in ("torch==2.13.0", "scenedetect==0.7.2"):
        assert pin in setup and pin in docker
