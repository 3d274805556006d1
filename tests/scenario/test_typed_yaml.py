"""The one YAML reader (duplicate keys refused at any depth) and the typed loader's required
fields, fixed-length tuples, keyword keys and self-checking dataclasses."""

from dataclasses import dataclass, field

import pytest

from mrta_drake.errors import InputError
from mrta_drake.scenario.typed_yaml import load_typed, read_yaml


def read(tmp_path, text: str):
    path = tmp_path / "file.yaml"
    path.write_text(text)
    return read_yaml(str(path), "test file")


def refusal(tmp_path, text: str) -> str:
    with pytest.raises(InputError) as error:
        read(tmp_path, text)
    message = str(error.value)
    assert "\n" not in message
    return message.removeprefix(f"{tmp_path / 'file.yaml'}: ")


@pytest.mark.parametrize("text, message", [
    ("a: 1\nb: 2\na: 3\n", "a: duplicate key 'a' at line 3 (first given at line 1)"),
    ("robots:\n  - {name: r1, start: [0, 0], name: r2}\n",
     "robots[0].name: duplicate key 'name' at line 2 (first given at line 2)"),
    ("x:\n  y:\n    z: 1\n    z: 2\n",
     "x.y.z: duplicate key 'z' at line 4 (first given at line 3)"),
    ('{"agents": [0, 1], "agents": [0]}', "agents: duplicate key 'agents' at line 1 (first given "
     "at line 1)"),
    ("1: a\n1.0: b\n", "1.0: duplicate key 1.0 at line 2 (first given at line 1)"),
])
def test_duplicate_keys_are_refused_at_any_depth(tmp_path, text, message):
    assert refusal(tmp_path, text) == message


def test_keys_that_load_differently_and_merged_keys_are_not_duplicates(tmp_path):
    assert read(tmp_path, '"1": a\n1: b\n') == {"1": "a", 1: "b"}
    text = "base: &base {speed: 1, radius: 0.2}\nrobot:\n  <<: *base\n  speed: 2\n"
    assert read(tmp_path, text)["robot"] == {"speed": 2, "radius": 0.2}


@pytest.mark.parametrize("text, message", [
    ("# nothing\n", "test file is empty"),
    ("a: [1, 2\nb: 3\n", "YAML syntax error at line 2, column 2: while parsing a flow "
     "sequence, expected ',' or ']', but got ':'"),
    ("a: 1\n---\nb: 2\n", "YAML syntax error at line 2, column 1: expected a single document "
     "in the stream, but found another document"),
])
def test_empty_and_malformed_files_name_the_line(tmp_path, text, message):
    assert refusal(tmp_path, text) == message


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="nowhere.yaml: test file not found$"):
        read_yaml(str(tmp_path / "nowhere.yaml"), "test file")


@dataclass(frozen=True)
class Segment:
    from_: tuple[float, float]
    to: tuple[float, float]
    width: float = 1.0

    def __post_init__(self):
        if self.width <= 0:
            raise InputError(None, "width", f"must be > 0, got {self.width:g}")


@dataclass(frozen=True)
class Drawing:
    name: str
    segments: list[Segment] = field(default_factory=list)


def test_keyword_fields_tuples_and_defaults_load():
    drawing = load_typed({"name": "d", "segments": [{"from": [0, 1], "to": [2, 3]}]},
                         Drawing, "d.yaml")
    assert drawing == Drawing("d", [Segment((0.0, 1.0), (2.0, 3.0), 1.0)])
    assert isinstance(drawing.segments[0].from_, tuple)


@pytest.mark.parametrize("data, message", [
    ({"segments": []}, "d.yaml: name: missing"),
    ({"name": "d", "segments": [{"from": [0, 1]}]}, "d.yaml: segments[0].to: missing"),
    ({"name": "d", "segments": [{"from": [0, 1, 2], "to": [0, 0]}]},
     "d.yaml: segments[0].from: expected a list of 2 numbers, got [0, 1, 2]"),
    ({"name": "d", "segments": [{"from_": [0, 1], "to": [0, 0]}]},
     "d.yaml: segments[0].from_: unknown field (known: from, to, width)"),
    ({"name": "d", "segments": [{"from": [0, 1], "to": [0, 0]}, {"from": [0, 1], "to": [0, 0],
                                                                  "width": -2}]},
     "d.yaml: segments[1].width: must be > 0, got -2"),
])
def test_typed_errors_name_the_field_path(data, message):
    with pytest.raises(InputError) as error:
        load_typed(data, Drawing, "d.yaml")
    assert str(error.value) == message
