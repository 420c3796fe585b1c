"""``documentation/index.html`` of an exported FMU: what the FMU is, in a page a user of an FMI tool opens.

It names the model and, for a simulation of a truth, the effects hidden in it; the system (basis, states,
speed, communication step); and every variable with its causality, unit, start value and description,
read back from the modelDescription the export wrote, so the page cannot disagree with it.
"""

from __future__ import annotations

import html
import json
from xml.etree import ElementTree as ET

from twin import __version__
from twin.fmu.truth import hidden_effects


def documentation_html(model_description: bytes, attrs: dict, step_s: float) -> str:
    """The page for an FMU from its ``modelDescription.xml`` and its system's attrs (``truth``, if any).

    Examples
    --------
    >>> xml = (b'<fmiModelDescription modelName="m" description="d"><ModelVariables>'
    ...        b'<ScalarVariable name="y" causality="output" description="out"><Real unit="m"/></ScalarVariable>'
    ...        b'</ModelVariables></fmiModelDescription>')
    >>> page = documentation_html(xml, {}, 0.01)
    >>> "<td>y</td><td>output</td><td>m</td>" in page
    True
    """
    root = ET.fromstring(model_description)
    name, description = root.get("modelName", ""), root.get("description", "")
    version = root.get("fmiVersion", "2.0")
    interfaces = " and ".join(
        label
        for tag, label in (("CoSimulation", "co-simulation"), ("ModelExchange", "model exchange"))
        if root.find(tag) is not None
    )
    rows = []
    for element in _variables(root):
        cells = (
            element.get("name", ""),
            element.get("causality", ""),
            element.get("unit", ""),
            element.get("start", ""),
            element.get("description", ""),
        )
        rows.append("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in cells) + "</tr>")
    truth = ""
    effects = hidden_effects(attrs)
    if effects is not None:
        items = "".join(
            f"<li><code>{html.escape(label)}</code>: {html.escape(json.dumps(values))}</li>"
            for label, values in effects.items()
        )
        truth = (
            "<h2>Truth</h2><p>This FMU simulates the model with hidden effects (a truth), for synthetic "
            f"measurements:</p><ul>{items or '<li>nothing hidden</li>'}</ul>"
        )
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(name)}</title></head>
<body>
<h1>{html.escape(name)}</h1>
<p>{html.escape(description)}</p>
<p>A linear rotor model exported by twin {html.escape(__version__)} as an FMI {html.escape(version)} FMU for
{html.escape(interfaces or "no interface")}. It is stepped in its modal form, exactly for a communication
step of any length; the outputs are proximeter displacements. Forces: the external inputs are held over a
step; the built-in 1X unbalance and the machine's white broad-band force (turbulence) are parameters, set before
initialisation, and linear between samples every {step_s:.12g} s from the start time. In model exchange
the host integrates the modal states, with a time event at each of those samples.</p>
{truth}
<h2>Variables</h2>
<table border="1" cellspacing="0" cellpadding="3">
<tr><th>name</th><th>causality</th><th>unit</th><th>start</th><th>description</th></tr>
{chr(10).join(rows)}
</table>
</body></html>
"""


def _variables(root: ET.Element) -> list[dict[str, str]]:
    """Each variable's attributes, its type element's merged in (FMI 2.0 nests them, FMI 3.0 does not)."""
    out = []
    for element in root.find("ModelVariables") if root.find("ModelVariables") is not None else []:
        attrs = dict(element.attrib)
        if element.tag == "ScalarVariable":
            kind = next(iter(element), None)
            attrs.update(kind.attrib if kind is not None else {})
        out.append(attrs)
    return out
