"""YAML helpers: syntax-error messages with file:line:column, the line of
every key path (so validation errors name it), duplicated keys refused."""
import yaml

from .checks import ROOT, ConfigError


def _yaml_error_message(fname, err):
    mark = getattr(err, "problem_mark", None) or getattr(err, "context_mark", None)
    where = f"{fname}:{mark.line + 1}:{mark.column + 1}" if mark is not None else fname
    parts = [p for p in (getattr(err, "context", None), getattr(err, "problem", None)) if p]
    detail = "; ".join(parts) if parts else str(err)
    return f"{where}: YAML syntax error: {detail}"


def _index_nodes(node, path, lines, fname, active):
    """Record the 1-based line of every key path; reject duplicated mapping keys."""
    if id(node) in active:  # recursive alias
        return
    lines.setdefault(path, node.start_mark.line + 1)
    active = active | {id(node)}
    if isinstance(node, yaml.MappingNode):
        seen = {}
        for knode, vnode in node.value:
            if not isinstance(knode, yaml.ScalarNode) or knode.tag == "tag:yaml.org,2002:merge":
                continue
            key = knode.value
            kpath = key if path == ROOT else f"{path}.{key}"
            if key in seen:
                raise ConfigError(
                    f"{fname}:{knode.start_mark.line + 1}: {kpath} is given twice (first on "
                    f"line {seen[key]}): expected each key once per mapping",
                    path=kpath)
            seen[key] = knode.start_mark.line + 1
            lines.setdefault(kpath, knode.start_mark.line + 1)
            _index_nodes(vnode, kpath, lines, fname, active)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            _index_nodes(item, f"{path}[{i}]", lines, fname, active)


def _line_for(path, lines):
    """Line of the longest prefix of ``path`` found in the YAML file, or None."""
    while path:
        if path in lines:
            return lines[path]
        cut = max(path.rfind("."), path.rfind("["))
        if cut <= 0:
            break
        path = path[:cut]
    return lines.get(path) if path else None
