"""The actuator models' C++ and the physics page's section 10 name each other: every function of
actuator_models.hpp cites a section of the page that exists, and every function the section
names is one of the header's."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
HEADER = ROOT / "stewart_env" / "_core" / "cpp" / "actuators" / "actuator_models.hpp"
PHYSICS = ROOT / "docs" / "physics.md"


def header_functions():
    """{name: comment} of the header's top-level functions, with the // lines right above each."""
    pattern = r"((?:^//.*\n)*)^(?:template <.*>\n)?(?:inline|constexpr)\b[^(;={}]*?\b(\w+)\("
    return {
        m.group(2): " ".join(line[2:].strip() for line in m.group(1).splitlines())
        for m in re.finditer(pattern, HEADER.read_text(), flags=re.M)
    }


def actuator_section():
    text = PHYSICS.read_text()
    start = text.index("## 10. Actuators\n")
    end = text.find("\n## ", start + 1)
    return text[start : end if end >= 0 else len(text)]


def test_every_function_cites_a_section_of_the_page_that_exists():
    functions = header_functions()
    assert len(functions) > 15  # the header was parsed
    headings = set(re.findall(r"^### (10\.\d+) ", actuator_section(), flags=re.M))
    uncited = [
        name for name, comment in functions.items() if not re.search(r"docs/physics\.md sections? 10\.\d", comment)
    ]
    assert uncited == []
    cited = {n for comment in functions.values() for n in re.findall(r"docs/physics\.md sections? (10\.\d)", comment)}
    assert cited <= headings


def test_every_function_the_section_names_is_in_the_header():
    named = set(re.findall(r"`(\w+)`", actuator_section()))
    functions = header_functions()
    # the section's names of the header's equations (others are config keys, classes, tests)
    equations = {n for n in named if "_" in n and n.islower() and n in functions}
    assert {
        "voltage_current_limit",
        "current_reference",
        "electric_force",
        "orifice_flow",
        "chamber_pressure",
    } <= equations
    assert {
        "lag_gain",
        "chamber_volumes",
        "hydraulic_force",
        "servo_gains",
        "bandwidth_ratio",
        "leg_servo_batch",
    } <= equations
