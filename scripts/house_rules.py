#!/usr/bin/env python3
"""The rules of the house that can be counted, checked on the tracked files (scripts/check.sh ci):

  file length      no .cc file over 600 lines;
  function length  no function over 100 lines (a definition at namespace scope: its
                   signature starts in column 0, its body ends at the next line that is
                   just "}" — the layout clang-format gives);
  boundaries       no file includes another module's internal/ header, and no public
                   header includes an internal/ one; the back-end neither includes nor
                   links the front-end;
  documents        README.md under 200 lines, bench/RESULTS.md under 400;
  spelling         identifiers spell -ize, as Eigen's and Ceres's do (Linearize, Factorize,
                   Normalize); prose in comments and documents keeps its own.

What is over a limit today is listed below with its present size: it may not grow, an
entry that shrank is lowered to its new size, and one that has come within its limit is
removed — so the lists only get shorter. Exits 1 naming every breach.

    scripts/house_rules.py [ROOT]      the rules on a checkout (default: this one)
    scripts/house_rules.py --self-test the function finder and the spelling check on examples
"""
import os
import re
import subprocess
import sys

FILE_LIMIT = 600
FUNCTION_LIMIT = 100
DOCUMENT_LIMITS = {"README.md": 200, "bench/RESULTS.md": 400}

# Over the limits today: path (or path:function) -> its present size, the most it may have.
FILES_OVER = {}
FUNCTIONS_OVER = {}
DOCUMENTS_OVER = {}

NOT_A_FUNCTION = re.compile(r"^(namespace|class|struct|enum|union|extern|using|typedef|template\s*<[^>]*>\s*(class|struct))\b")


BRITISH_IDENTIFIER = re.compile(
    r"\b\w*(Summaris|Normalis|Linearis|Initialis|Regularis|Factoris|Marginalis|Optimis|Minimis|Maximis)\w*\b")


def code_part(line):
    """The line without its // comment and string literals (roughly: enough for identifiers)."""
    line = re.sub(r'"(\\.|[^"\\])*"', '""', line)
    return line.split("//", 1)[0]


def tracked(root, *patterns):
    out = subprocess.run(["git", "-C", root, "ls-files", *patterns], check=True, capture_output=True, text=True)
    return [p for p in out.stdout.splitlines() if os.path.exists(os.path.join(root, p))]


def lines_of(root, path):
    with open(os.path.join(root, path), encoding="utf-8") as f:
        return f.read().splitlines()


def functions(lines):
    """(name, first line, body length) of each definition at namespace scope."""
    found = []
    i = 0
    while i < len(lines):
        line = lines[i]
        if not line or line[0] in " \t#/}*" or NOT_A_FUNCTION.match(line) or "(" not in line:
            i += 1
            continue
        j = i  # the signature may go on over indented lines: find its end
        while j < len(lines) and not lines[j].rstrip().endswith(("{", ";", "}")):
            j += 1
        if j >= len(lines) or not lines[j].rstrip().endswith("{"):
            i = j + 1
            continue
        k = j + 1
        while k < len(lines) and lines[k] != "}":
            k += 1
        name = re.search(r"([~\w:]+(?:<[^(]*>)?|operator\S+)\s*\(", line)
        found.append((name.group(1) if name else line.strip(), i + 1, k - j - 1))
        i = k + 1
    return found


def module_of(path):
    parts = path.split("/")
    return parts[1] if parts[0] in ("tests", "fuzz") and len(parts) > 2 else parts[0]


def check_limits(kind, measured, limit, over):
    """Breaches of `limit` among measured {key: size}, with `over` the listed exceptions."""
    problems = []
    for key, size in sorted(measured.items()):
        if key in over:
            if size > over[key]:
                problems.append(f"{kind} {key}: {size} lines, grown past its listed {over[key]} (limit {limit})")
            elif limit < size < over[key]:
                problems.append(f"{kind} {key} shrank to {size} lines: lower its entry in scripts/house_rules.py")
        elif size > limit:
            problems.append(f"{kind} {key}: {size} lines, over the limit of {limit}")
    for key, most in sorted(over.items()):
        if measured.get(key, 0) <= limit:
            problems.append(f"{kind} {key} is now within {limit} lines: remove it from scripts/house_rules.py")
    return problems


def self_test():
    """The function finder on the layouts clang-format gives, and the spelling check."""
    example = """namespace subslam {
namespace {

int Short(int a) {
  return a;
}

}  // namespace

absl::StatusOr<std::vector<int>> Wrapped(const std::string& a,
                                         int b) {
  if (b) {
    return {};
  }
  return std::vector<int>{1};
}

class Skipped {
 public:
  void Inline() {
    int x = 0;
  }
};

double Declared(int a);

Widget::Widget(int a)
    : a_(a) {
  Run();
}
}  // namespace subslam"""
    found = functions(example.splitlines())
    expected = [("Short", 4, 1), ("Wrapped", 10, 4), ("Widget::Widget", 27, 1)]
    if found != expected:
        print(f"house_rules: self-test: found {found}, expected {expected}")
        return 1
    spelled = {line: bool(BRITISH_IDENTIFIER.search(code_part(line)))
               for line in ["  void Normalise();", "  // Normalise the weights", '  Log("Factorisation failed");',
                            "int LinearisedCost = 0;", "  void Normalize();"]}
    if list(spelled.values()) != [True, False, False, True, False]:
        print(f"house_rules: self-test: spelling check {spelled}")
        return 1
    print("house_rules: self-test passed")
    return 0


def main():
    if sys.argv[1:] == ["--self-test"]:
        return self_test()
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
    sources = tracked(root, "*.cc", "*.h")
    problems = []
    file_sizes = {p: len(lines_of(root, p)) for p in sources if p.endswith(".cc")}
    problems += check_limits("file", file_sizes, FILE_LIMIT, FILES_OVER)
    function_sizes = {}
    for path in sources:
        for name, line, size in functions(lines_of(root, path)):
            function_sizes[f"{path}:{name}"] = max(size, function_sizes.get(f"{path}:{name}", 0))
    problems += check_limits("function", function_sizes, FUNCTION_LIMIT, FUNCTIONS_OVER)
    documents = {p: len(lines_of(root, p)) for p in DOCUMENT_LIMITS}
    for path, limit in DOCUMENT_LIMITS.items():
        problems += check_limits("document", {path: documents[path]}, limit,
                                 {path: DOCUMENTS_OVER[path]} if path in DOCUMENTS_OVER else {})
    include = re.compile(r'#include\s+"subslam/(\w+)/internal/([^"]+)"')
    for path in sources:
        public = "/include/subslam/" in path and "/internal/" not in path
        for number, line in enumerate(lines_of(root, path), 1):
            m = include.match(line)
            if not m:
                continue
            if public or m.group(1) != module_of(path):
                problems.append(f"boundary {path}:{number}: includes {m.group(1)}'s internal header "
                                f"{m.group(2)}" + (" from a public header" if public else ""))
    for path in sources:
        if path.startswith("backend/"):  # the library (its tests may drive a front-end)
            for number, line in enumerate(lines_of(root, path), 1):
                if line.startswith('#include "subslam/frontend/'):
                    problems.append(f"boundary {path}:{number}: the back-end includes the front-end")
    for path in sources:
        for number, line in enumerate(lines_of(root, path), 1):
            m = BRITISH_IDENTIFIER.search(code_part(line))
            if m:
                problems.append(f"spelling {path}:{number}: identifier {m.group(0)} (identifiers spell -ize)")
    backend_cmake = "\n".join(lines_of(root, "backend/CMakeLists.txt"))
    if re.search(r"subslam::frontend|subslam_frontend", backend_cmake):
        problems.append("boundary backend/CMakeLists.txt: the back-end links the front-end")
    for p in problems:
        print(f"house_rules: {p}")
    print(f"house_rules: {len(sources)} files, {len(function_sizes)} functions: "
          + ("clean" if not problems else f"{len(problems)} problems"))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
