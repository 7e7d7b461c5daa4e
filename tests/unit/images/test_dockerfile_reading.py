"""Reading Dockerfiles for their build arguments and the context files COPY and ADD use."""

from __future__ import annotations

from pathlib import Path

import pytest
from coral_testbed.images import dockerfiles

HERE = Path("Dockerfile")


def test_copy_and_add_sources_are_found_across_continuations_and_forms() -> None:
    text = (
        "# comment\nARG BASE=python:3.11-slim-bookworm\nFROM ${BASE}\n"
        "COPY --chown=1:1 a.txt \\\n    b.txt /dst/\n"
        'ADD ["c dir", "/x"]\n'
        "COPY --from=builder /out /out\n"
        "RUN echo done\n"
    )
    parsed = dockerfiles.parse(text, HERE)
    assert parsed.context_sources() == ["a.txt", "b.txt", "c dir"]
    assert parsed.args() == {"BASE": "python:3.11-slim-bookworm"}


def test_a_source_built_from_an_arg_means_the_whole_context() -> None:
    parsed = dockerfiles.parse("FROM scratch\nARG SRC\nCOPY $SRC /x\n", HERE)
    assert parsed.context_sources() is None


@pytest.mark.parametrize(
    ("text", "message"),
    [
        pytest.param("RUN echo\n", "Dockerfile: no FROM instruction", id="no FROM"),
        pytest.param("FROM scratch\nCOPY \\\n", "Dockerfile:2: the last instruction ends", id="dangling \\"),
        pytest.param("FROM scratch\n--x y\n", "Dockerfile:2: '--x' is not a Dockerfile", id="not one"),
    ],
)
def test_bad_dockerfiles_are_refused_with_file_and_line(text: str, message: str) -> None:
    with pytest.raises(dockerfiles.DockerfileError, match=message):
        dockerfiles.parse(text, HERE)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        pytest.param("FROM scratch\nCOPY only-one\n", "Dockerfile:2: COPY needs a source", id="no dest"),
        pytest.param('FROM scratch\nCOPY ["a", \n', "Dockerfile:2: COPY JSON form is invalid", id="JSON"),
    ],
)
def test_bad_copy_instructions_name_their_line(text: str, message: str) -> None:
    with pytest.raises(dockerfiles.DockerfileError, match=message):
        dockerfiles.parse(text, HERE).context_sources()
