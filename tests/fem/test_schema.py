"""The model file's declaration: the reader reads every declared key by it, and the reference page lists them."""

import re

import pytest

from twin.errors import ModelFileError
from twin.fem.effects import effect_classes
from twin.fem.modelfile import load_model, shipped_model
from twin.fem.schema import KINDS, REQUIRED, RULES, SECTIONS, Section, reference_markdown, section

#: A model with what the shipped ones leave out: G instead of poisson, element lengths, the shaft physics
#: switched off, sensor directions, every [excitation] and [damping] key.
EXTRA = """
[model]
name = "extra"
speed_rpm = 3000.0
shear_deformation = false
rotary_inertia = false
gyroscopic = false
[materials.steel]
E = 2.1e11
G = 8.1e10
rho = 7810.0
[[shaft]]
nodes = [0, 2]
material = "steel"
outer_diameter = 0.05
inner_diameter = 0.0
element_lengths = [0.25, 0.25]
[[disk]]
name = "D1"
node = 1
mass = 10.0
Id = 0.1
Ip = 0.2
[[bearing]]
name = "B0"
node = 0
kxx = 1e6
kxy = 0.0
kyx = 0.0
kyy = 1e6
cxx = 100.0
cxy = 0.0
cyx = 0.0
cyy = 100.0
[[bearing]]
name = "B2"
node = 2
kxx = 1e6
kxy = 0.0
kyx = 0.0
kyy = 1e6
cxx = 100.0
cxy = 0.0
cyx = 0.0
cyy = 100.0
[[sensor]]
name = "S1"
node = 1
directions = ["y"]
[damping]
shaft_mass_proportional = 0.1
shaft_stiffness_proportional = 1e-5
[excitation]
unbalance_at = "D1"
unbalance_me = 1e-4
balance_grade = 6.3
broadband_at = 1
broadband_asd = 0.1
max_response = 1e-3
"""


def test_every_declared_key_is_read_by_its_declaration(tmp_path, monkeypatch):
    asked = set()
    key = Section.key

    def recording(self, name):
        asked.add((self.header, name))
        return key(self, name)

    monkeypatch.setattr(Section, "key", recording)
    (tmp_path / "extra.toml").write_text(EXTRA)
    for path in (shipped_model("hydro_unit"), shipped_model("ross_reference"), tmp_path / "extra.toml"):
        load_model(path)
    declared = {(s.header, k.name) for s in SECTIONS for k in s.keys}
    assert declared - asked == set(), "declared but never read by the declaration"
    for s in SECTIONS:
        for k in s.keys:
            assert k.kind in KINDS and (not k.rule or k.rule in RULES) and k.doc, (s.header, k.name)


def test_a_key_the_reader_asks_for_must_be_declared():
    with pytest.raises(KeyError, match=r"\[model\] declares no key 'speed'"):
        section("[model]").key("speed")


def test_a_rule_of_the_declaration_is_the_reader_s(tmp_path):
    text = shipped_model("ross_reference").read_text()
    path = tmp_path / "m.toml"
    path.write_text(text.replace("kxx = 1.0e6", "kxx = -1.0e6", 1))
    with pytest.raises(ModelFileError, match=r"\[\[bearing\]\] 'B0'.*'kxx'.*must be positive"):
        load_model(path)


def test_the_reference_lists_every_table_key_and_effect():
    text = reference_markdown()
    for sec in SECTIONS:
        assert f"## `{sec.header}`" in text
        for k in sec.keys:
            assert f"| `{k.name}` |" in text, (sec.header, k.name)
            if k.default is REQUIRED and not k.default_text:
                assert re.search(rf"\| `{k.name}` \|[^\n]*\| required \|", text), k.name
    for key, cls in effect_classes(local=False).items():
        assert cls.per_mode or f"{key}" in text, key
    assert "`immersed` (`fsi`, `fsi_per_mode`)" in text
