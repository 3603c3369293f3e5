"""No function of fmm_ros runs past 80 lines, numba kernels apart (a kernel is one loop the
compiler sees whole)."""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / 'fmm_ros'
MAX_LINES = 80


def is_numba_kernel(node: ast.FunctionDef) -> bool:
    names = {ast.unparse(d).split('(')[0].rsplit('.', 1)[-1] for d in node.decorator_list}
    return bool(names & {'njit', 'jit', 'vectorize', 'guvectorize'})


def function_lengths() -> dict[tuple[str, str], int]:
    lengths = {}
    for path in sorted(PACKAGE.rglob('*.py')):
        module = path.relative_to(PACKAGE).as_posix()
        for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                if not is_numba_kernel(node):
                    length = node.end_lineno - node.lineno + 1
                    lengths[module, node.name] = max(length, lengths.get((module, node.name), 0))
    return lengths


def test_no_function_runs_past_80_lines():
    too_long = {key: length for key, length in function_lengths().items() if length > MAX_LINES}
    assert too_long == {}, f'split these (at most {MAX_LINES} lines): {too_long}'


def test_the_kernel_rule_sees_a_numba_kernel():
    tree = ast.parse(
        '@njit(cache=True)\ndef f():\n    pass\n\n@functools.cache\ndef g():\n    pass\n'
    )
    kernel, plain = tree.body
    assert is_numba_kernel(kernel) and not is_numba_kernel(plain)
