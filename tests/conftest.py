"""Every convert report the test-suite makes in this process is validated against ``recon/report.schema.json``.

``recon.pipeline._report`` (every :func:`recon.convert`) and ``recon._io.write_json`` (every report written, after
:func:`recon.verdict.write_checked` judged the written file) are looked up by name when called, so wrapping them here
sees every report, whichever way a test reaches them. Reports of CLI runs in a subprocess are not seen here.
"""

from __future__ import annotations

import functools

import pytest


@pytest.fixture(autouse=True, scope="session")
def _reports_follow_the_schema():
    import jsonschema

    import recon._io
    import recon.pipeline
    from recon.verdict import schema

    validator = jsonschema.Draft202012Validator(schema())
    made, wrote = recon.pipeline._report, recon._io.write_json

    @functools.wraps(made)
    def checked_report(*args, **kwargs):
        report = made(*args, **kwargs)
        validator.validate(report)
        return report

    @functools.wraps(wrote)
    def checked_write(path, data, *args, **kwargs):
        if isinstance(data, dict) and "verdict" in data and "faces_by_type" in data:
            validator.validate(data)
        return wrote(path, data, *args, **kwargs)

    recon.pipeline._report, recon._io.write_json = checked_report, checked_write
    yield
    recon.pipeline._report, recon._io.write_json = made, wrote
