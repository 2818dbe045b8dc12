"""Every test method written in tests/integration/*_test.py is registered as a ctest in
tests/integration/CMakeLists.txt (mapmesh_python_tests), and every registered case exists: a case
that is written but not listed never runs on CI (HugeSubmapsTest was, for one commit)."""

import ast
import re
import unittest
from pathlib import Path

HERE = Path(__file__).resolve().parent


def registered():
    text = (HERE / "CMakeLists.txt").read_text()
    text = re.sub(r"#[^\n]*", "", text)  # comments (the function's own usage line among them)
    cases = set()
    for module, body in re.findall(r"mapmesh_python_tests\((\w+)\s+([^)]*)\)", text):
        cases.update(f"{module}.{case}" for case in body.split())
    return cases


def written():
    cases = set()
    for path in HERE.glob("*_test.py"):
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, ast.ClassDef):
                cases.update(f"{path.stem}.{node.name}.{f.name}" for f in node.body
                             if isinstance(f, ast.FunctionDef) and f.name.startswith("test"))
    return cases


class RegistryTest(unittest.TestCase):
    def test_every_integration_test_method_is_a_ctest(self):
        reg, made = registered(), written()
        self.assertGreater(len(made), 100)
        self.assertEqual(sorted(made - reg), [], "written but not registered in tests/integration/CMakeLists.txt")
        self.assertEqual(sorted(reg - made), [], "registered but not written")


if __name__ == "__main__":
    unittest.main()
