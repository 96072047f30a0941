"""The body model: smplx's SMPL over a user's SMPL file or a procedural SMPL-format body."""

from multithumbs.body.model import BodyModel, BodyOutput, load_body_model
from multithumbs.body.procedural import (
    PROCEDURAL_MODEL_VERSION, build_procedural_smpl, procedural_model_path, write_procedural_smpl,
)

__all__ = ["BodyModel", "BodyOutput", "PROCEDURAL_MODEL_VERSION", "build_procedural_smpl",
           "load_body_model", "procedural_model_path", "write_procedural_smpl"]
