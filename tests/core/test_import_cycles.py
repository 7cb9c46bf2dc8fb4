"""No import cycle among the project's modules (lazy, function-level imports included): a cycle
hides a layering mistake that import-linter's contract, which checks packages, can miss."""

import grimp

PACKAGES = ("macrostate_mj", "collectors", "estimators", "viz")


def find_cycle(graph: grimp.ImportGraph) -> list[str] | None:
    """One import cycle (its modules, the first repeated at the end), or None: a depth-first
    search that meets a module still on its path."""
    done: set[str] = set()
    for root in sorted(graph.modules):
        if root in done:
            continue
        path, on_path = [root], {root}
        stack = [iter(sorted(graph.find_modules_directly_imported_by(root)))]
        while stack:
            nxt = next(stack[-1], None)
            if nxt is None:
                stack.pop()
                done.add(path[-1])
                on_path.discard(path.pop())
            elif nxt in on_path:
                return [*path[path.index(nxt):], nxt]
            elif nxt not in done:
                path.append(nxt)
                on_path.add(nxt)
                stack.append(iter(sorted(graph.find_modules_directly_imported_by(nxt))))
    return None


def test_the_project_has_no_import_cycle():
    graph = grimp.build_graph(*PACKAGES)
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_the_search_finds_a_cycle():
    graph = grimp.ImportGraph()
    for a, b in (("p.a", "p.b"), ("p.b", "p.c"), ("p.c", "p.a"), ("p.d", "p.a")):
        graph.add_import(importer=a, imported=b)
    assert find_cycle(graph) == ["p.a", "p.b", "p.c", "p.a"]
    graph.remove_import(importer="p.c", imported="p.a")
    assert find_cycle(graph) is None
