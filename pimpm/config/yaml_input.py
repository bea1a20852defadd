"""YAML helpers: reading an input file safely (size, kind of file, nesting,
aliases), syntax-error messages with file:line:column, the line of every
key path (so validation errors name it), duplicated keys refused.

Limits on what an input may be (docs/INPUT.md, docs/RELIABILITY.md):
a regular file (not a FIFO or a device) of at most :data:`MAX_INPUT_BYTES`,
nested at most :data:`MAX_DEPTH` levels, with at most :data:`MAX_NODES`
values once aliases are expanded, and no alias inside its own anchor. These
are checked on the parser's event stream (libyaml's C parser when present)
before anything is built, so an alias bomb or a self-referencing alias costs
nothing."""
import os
import stat

import yaml

from .checks import ROOT, ConfigError

#: the largest input file read (an input is a page or two; a table of 30,000 points
#: still fits; particle clouds and meshes are read from their own files)
MAX_INPUT_BYTES = 2**20
#: the deepest nesting of lists and mappings accepted
MAX_DEPTH = 64
#: the most values (scalars, lists, mappings), aliases expanded
MAX_NODES = 2_000_000

Loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)       # libyaml's C parser when installed


def read_yaml(fname):
    """The data of the YAML file ``fname`` and the line of every key path,
    parsed once; ConfigError for a file that is not a readable regular file
    within the limits above, a syntax error or a duplicated key."""
    try:
        info = os.stat(fname)
    except FileNotFoundError:
        raise ConfigError(f"{fname}: file not found: expected an existing YAML input file") from None
    except OSError as err:
        raise ConfigError(f"{fname}: cannot read file ({err.strerror}): expected a readable "
                          f"YAML input file") from None
    if not stat.S_ISREG(info.st_mode):
        kind = ("a directory" if stat.S_ISDIR(info.st_mode) else "a FIFO" if stat.S_ISFIFO(info.st_mode)
                else "a device" if stat.S_ISCHR(info.st_mode) or stat.S_ISBLK(info.st_mode)
                else "not a regular file")
        raise ConfigError(f"{fname}: is {kind}: expected a regular YAML input file")
    if info.st_size > MAX_INPUT_BYTES:
        raise ConfigError(f"{fname}: {info.st_size} bytes: expected an input file of at most "
                          f"{MAX_INPUT_BYTES} bytes ({MAX_INPUT_BYTES // 2**20} MiB)")
    try:
        with open(fname, "rb") as fh:
            data = fh.read(MAX_INPUT_BYTES + 1)
        text = data.decode("utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise ConfigError(f"{fname}: cannot read file ({err.__class__.__name__}: {err}): "
                          f"expected a readable UTF-8 YAML input file") from None
    if len(data) > MAX_INPUT_BYTES:
        raise ConfigError(f"{fname}: more than {MAX_INPUT_BYTES} bytes: expected an input file "
                          f"of at most {MAX_INPUT_BYTES // 2**20} MiB")
    return parse_text(fname, text)


def parse_text(name, text):
    """(data, the line of every key path) of the YAML ``text`` within the
    limits above (depth, expanded size, no self-referencing alias, each key
    once per mapping): the one parser of every YAML pimpm reads, input
    files and ``--set`` values alike (``name`` says where the text came
    from in messages). ConfigError for a syntax error or a text beyond the
    limits."""
    if len(text) > MAX_INPUT_BYTES:
        raise ConfigError(f"{name}: more than {MAX_INPUT_BYTES} characters: expected at most "
                          f"{MAX_INPUT_BYTES // 2**20} MiB of YAML")
    try:
        _check_events(name, text)
        loader = Loader(text)
        try:
            node = loader.get_single_node()
            lines = {}
            if node is not None:
                # before the construction, which flattens merge keys (<<: *base) into
                # the mapping: a key given beside a merge overrides it, it is no duplicate
                _index_nodes(node, ROOT, lines, name, set())
            raw = loader.construct_document(node) if node is not None else None
        finally:
            loader.dispose()
    except yaml.YAMLError as err:
        raise ConfigError(_yaml_error_message(name, err)) from None
    return raw, lines


def _check_events(fname, text):
    """Depth, expanded size and self-reference of aliases, from the parser's
    events (nothing is built)."""
    depth = 0
    size = {}              # anchor -> number of values it stands for
    open_anchors = []      # [anchor, values counted when it opened] of open collections
    total = 0
    for event in yaml.parse(text, Loader=Loader):
        if isinstance(event, yaml.AliasEvent):
            if event.anchor in (a for a, _ in open_anchors):
                line = event.start_mark.line + 1
                raise ConfigError(f"{fname}:{line}: alias *{event.anchor} refers to the anchor it is "
                                  f"inside of: expected no self-referencing aliases")
            total += size.get(event.anchor, 1)
        elif isinstance(event, (yaml.ScalarEvent, yaml.SequenceStartEvent, yaml.MappingStartEvent)):
            total += 1
            if isinstance(event, yaml.ScalarEvent):
                if event.anchor is not None:
                    size[event.anchor] = 1
            else:
                depth += 1
                open_anchors.append((event.anchor, total - 1))
                if depth > MAX_DEPTH:
                    raise ConfigError(f"{fname}:{event.start_mark.line + 1}: lists and mappings nested "
                                      f"more than {MAX_DEPTH} deep: expected at most {MAX_DEPTH} levels")
        elif isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
            depth -= 1
            anchor, start = open_anchors.pop()
            if anchor is not None:
                size[anchor] = total - start
        if total > MAX_NODES:
            raise ConfigError(f"{fname}: more than {MAX_NODES} values once aliases are expanded: "
                              f"expected an input of at most {MAX_NODES} values (an alias bomb?)")


def _yaml_error_message(fname, err):
    mark = getattr(err, "problem_mark", None) or getattr(err, "context_mark", None)
    where = f"{fname}:{mark.line + 1}:{mark.column + 1}" if mark is not None else fname
    parts = [p for p in (getattr(err, "context", None), getattr(err, "problem", None)) if p]
    detail = "; ".join(parts) if parts else str(err)
    return f"{where}: YAML syntax error: {detail}"


def _index_nodes(node, path, lines, fname, seen_nodes):
    """Record the 1-based line of every key path; reject duplicated mapping
    keys. A node reached again through an alias is not walked again."""
    lines.setdefault(path, node.start_mark.line + 1)
    if id(node) in seen_nodes:
        return
    seen_nodes.add(id(node))
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
            _index_nodes(vnode, kpath, lines, fname, seen_nodes)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            _index_nodes(item, f"{path}[{i}]", lines, fname, seen_nodes)


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
