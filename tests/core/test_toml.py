"""The one TOML writer: what it writes reads back with tomllib to the same data."""
import math
import tomllib

import pytest

from sinslab.core.toml import dump_toml, toml_value


def test_round_trip_tables_and_arrays_of_tables():
    doc = {"name": 'a "quoted" \\ name', "n": 3, "x": 0.1, "flag": True, "v": [1.0, 2.5, -3.0],
           "start": {"lat": "32 deg", "h": "1000 m"},
           "segment": [{"kind": "static", "duration": "10 s"},
                       {"kind": "turn", "rate": "1.5 deg/s", "sub": {"ramp": "5 s"}}]}
    text = dump_toml(doc, array_tables=True)
    assert "[[segment]]" in text and text.count("[[segment]]") == 2
    assert tomllib.loads(text) == doc
    inline = dump_toml(doc)                      # default: a list of tables stays inline
    assert "[[segment]]" not in inline and tomllib.loads(inline) == doc


def test_dotted_table_none_and_special_floats():
    text = dump_toml({"a": 1, "skip": None, "sub": {"b": [1, 2]}}, table="sim.imu")
    assert text.startswith("[sim.imu]\n") and "skip" not in text
    assert tomllib.loads(text) == {"sim": {"imu": {"a": 1, "sub": {"b": [1, 2]}}}}
    assert dump_toml({}, table="imu") == "[imu]\n" and dump_toml({}) == ""
    back = tomllib.loads(dump_toml({"p": math.inf, "m": -math.inf, "q": math.nan}))
    assert back["p"] == math.inf and back["m"] == -math.inf and math.isnan(back["q"])
    with pytest.raises(TypeError, match="cannot write object"):
        toml_value(object())
