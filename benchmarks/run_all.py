"""`make bench`: run every benchmark of write_reference.MAKE_BENCH, print its output, and rewrite
its measured section of docs/accuracy.md (`<!-- bench:NAME -->`) as soon as it finishes, so a
later failure loses nothing already measured. Sections that are not `make bench`'s are rerun by
hand: ``python benchmarks/write_reference.py KEY`` (see that module)."""

from __future__ import annotations

import importlib
import platform

from write_reference import DOC, MAKE_BENCH, ROOT, SELF_WRITTEN, write

if __name__ == "__main__":
    modules = [importlib.import_module(name) for name in MAKE_BENCH]  # import errors stop first
    print(
        f"machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}"
    )
    doc = DOC.relative_to(ROOT)
    for module in modules:
        name = module.__name__
        print(f"\n## {name}\n{module.__doc__.strip()}\n")
        output = module.main()
        print(output)
        if name in SELF_WRITTEN:
            print(f"\n({name} wrote its own section of {doc})")
        elif write({name: output}):
            print(f"\n(rewrote the section `bench:{name}` of {doc})")
        else:
            print(f"\n(no section `bench:{name}` in {doc}: printed only)")
