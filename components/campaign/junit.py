"""JUnit XML: one testsuite per (procedure, system), one testcase per case; a failed criterion
is a <failure>, an errored case an <error>, each with its message; a case none of whose criteria
applies (a noise-free IMU against criteria on σ) is <skipped>. No times: the file depends
only on the results (CI systems show each case)."""
from __future__ import annotations

from xml.etree import ElementTree as ET


def junit_xml(camp, records: dict) -> str:
    root = ET.Element("testsuites", name=f"calbench campaign {camp.name}")
    suites = {}
    for case in camp.cases:
        key = f"{case.procedure}.{case.system}"
        if key not in suites:
            suites[key] = ET.SubElement(root, "testsuite", name=f"{camp.name}.{key}")
        rec = records.get(case.id)
        tc = ET.SubElement(suites[key], "testcase", classname=f"{camp.name}.{key}", name=case.id)
        props = ET.SubElement(tc, "properties")
        ET.SubElement(props, "property", name="seed", value=str(case.seed))
        for k, v in case.variation.items():
            ET.SubElement(props, "property", name=k, value=repr(v))
        if rec is None:
            ET.SubElement(tc, "skipped", message="not run (campaign incomplete)")
            continue
        for r in rec["criteria"]:
            ET.SubElement(props, "property", name=f"criterion {r['id']} ({r['requirement']})",
                          value="pass" if r["passed"] else "not applicable" if r.get("applicable") is False
                          else "not evaluated" if r["passed"] is None else "fail")
        judged = [r for r in rec["criteria"] if r.get("applicable") is not False]
        if rec["criteria"] and not judged and rec["verdict"] != "error":
            # nothing of this case could be judged (e.g. a noise-free IMU and criteria on σ): a
            # CI must not count it as passed
            ET.SubElement(tc, "skipped", message="every criterion not applicable: " + "; ".join(
                dict.fromkeys(r["message"] for r in rec["criteria"])))
            continue
        if rec["verdict"] == "error":
            e = ET.SubElement(tc, "error", message=rec["reason"] or "error", type="CaseError")
            e.text = rec["reason"]
        elif rec["verdict"] == "fail":
            bad = [r for r in rec["criteria"] if r["passed"] is False]
            f = ET.SubElement(tc, "failure", message="; ".join(f"{r['id']} ({r['requirement']})" for r in bad),
                              type="AcceptanceCriterion")
            f.text = "\n".join(f"{r['id']} [{r['requirement']}]: {r['message']}" for r in bad)
    for s in suites.values():
        cases = s.findall("testcase")
        s.set("tests", str(len(cases)))
        s.set("failures", str(sum(c.find("failure") is not None for c in cases)))
        s.set("errors", str(sum(c.find("error") is not None for c in cases)))
        s.set("skipped", str(sum(c.find("skipped") is not None for c in cases)))
    for k in ("tests", "failures", "errors", "skipped"):
        root.set(k, str(sum(int(s.get(k)) for s in suites.values())))
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
