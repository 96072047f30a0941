from tests.export.conftest import small_scene  # noqa: F401  (shared session fixture)
