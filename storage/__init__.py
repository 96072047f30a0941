"""Content-addressed artifacts (DESIGN §5). Imports no Prefect; ``multithumbs`` does not import this."""
