#!/usr/bin/env python3
"""The library's public API as a sorted listing, one item a line, from rustdoc's JSON output.

Usage: scripts/public_api.py target/doc/clipsat.json > docs/public-api.txt
(`.ci/public-api` builds the JSON and diffs the listing with the committed one.)

Every item reachable from the crate root by a public path is listed with its kind and signature:
modules, structs, enums and their variants, public fields, functions, inherent methods, associated and
free constants, type aliases, traits. Trait impls are listed as one `impl` line per type (not counted
as items): which traits a type implements is part of its contract too. The last line counts the items.
"""

import json
import sys


def ty(t):
    """A rustdoc JSON type, as Rust source."""
    if t is None:
        return "()"
    (k, v), = t.items()
    if k == "primitive":
        return v
    if k == "generic":
        return v
    if k == "resolved_path":
        # A crate-internal path of a re-exported type reads as the name the root exports it by.
        path = v["path"].rsplit("::", 1)[-1] if v["path"].startswith("crate::") else v["path"]
        return path + args(v.get("args"))
    if k == "borrowed_ref":
        life = (v["lifetime"] + " ") if v.get("lifetime") else ""
        return "&" + life + ("mut " if v["is_mutable"] else "") + ty(v["type"])
    if k == "tuple":
        return "(" + ", ".join(ty(x) for x in v) + ")"
    if k == "slice":
        return "[" + ty(v) + "]"
    if k == "array":
        return "[" + ty(v["type"]) + "; " + v["len"] + "]"
    if k == "raw_pointer":
        return "*" + ("mut " if v["is_mutable"] else "const ") + ty(v["type"])
    if k == "impl_trait":
        return "impl " + " + ".join(bound(b) for b in v)
    if k == "dyn_trait":
        parts = [poly(p) for p in v["traits"]]
        if v.get("lifetime"):
            parts.append(v["lifetime"])
        return "dyn " + " + ".join(parts)
    if k == "qualified_path":
        return "<" + ty(v["self_type"]) + ">::" + v["name"]
    if k == "function_pointer":
        sig = v["sig"]
        return "fn(" + ", ".join(ty(x[1]) for x in sig["inputs"]) + ")" + ret(sig["output"])
    return k


def poly(p):
    tr = p["trait"]
    return tr["path"] + args(tr.get("args"))


def args(a):
    if not a:
        return ""
    if "angle_bracketed" in a:
        ab = a["angle_bracketed"]
        parts = []
        for x in ab["args"]:
            (k, v), = x.items()
            if k == "type":
                parts.append(ty(v))
            elif k == "const":
                parts.append(v.get("expr", "_"))
            else:
                parts.append(v if isinstance(v, str) else str(v))
        for c in ab.get("constraints", []):
            parts.append(c["name"] + " = " + ty(c["binding"].get("equality", {}).get("type")))
        return "<" + ", ".join(parts) + ">" if parts else ""
    if "parenthesized" in a:
        p = a["parenthesized"]
        return "(" + ", ".join(ty(x) for x in p["inputs"]) + ")" + ret(p.get("output"))
    return ""


def bound(b):
    if "trait_bound" in b:
        return poly(b["trait_bound"])
    if "outlives" in b:
        return b["outlives"]
    return "?"


def ret(o):
    return "" if o is None else " -> " + ty(o)


def generics(g):
    ps = []
    for p in g.get("params", []):
        kind = p["kind"]
        if "lifetime" in kind:
            ps.append(p["name"])
        elif "type" in kind:
            bounds = kind["type"].get("bounds", [])
            if kind["type"].get("is_synthetic"):
                continue
            ps.append(p["name"] + (": " + " + ".join(bound(b) for b in bounds) if bounds else ""))
        elif "const" in kind:
            ps.append("const " + p["name"] + ": " + ty(kind["const"]["type"]))
    return "<" + ", ".join(ps) + ">" if ps else ""


def fn_sig(name, f):
    ins = []
    for n, t in f["sig"]["inputs"]:
        if n == "self":
            ins.append({"&Self": "&self", "&mut Self": "&mut self", "Self": "self"}.get(ty(t), "self: " + ty(t)))
        else:
            ins.append(n + ": " + ty(t))
    return "fn " + name + generics(f["generics"]) + "(" + ", ".join(ins) + ")" + ret(f["sig"]["output"])


class Lister:
    def __init__(self, doc):
        self.index = doc["index"]
        self.lines = []
        self.items = 0
        self.seen = set()

    def item(self, i):
        return self.index.get(str(i)) or self.index.get(i)

    def add(self, line, counted=True):
        self.lines.append(line)
        if counted:
            self.items += 1

    def module(self, m, path):
        for child in m["inner"]["module"]["items"]:
            it = self.item(child)
            if it is None or it["visibility"] != "public":
                continue
            (kind, inner), = it["inner"].items()
            if kind == "use":
                if inner.get("is_glob"):
                    raise SystemExit("glob re-export in the public API: " + path)
                target = self.item(inner["id"]) if inner.get("id") is not None else None
                if target is None:
                    self.add("pub use " + path + "::" + inner["name"] + " = " + inner["source"])
                    continue
                self.visit(target, path + "::" + inner["name"])
            else:
                self.visit(it, path + "::" + it["name"])

    def visit(self, it, path):
        key = (it["id"], path)
        if key in self.seen:
            return
        self.seen.add(key)
        (kind, inner), = it["inner"].items()
        if kind == "module":
            self.add("pub mod " + path)
            self.module(it, path)
        elif kind == "struct":
            self.add("pub struct " + path + generics(inner["generics"]))
            sk = inner["kind"]
            if "plain" in sk:
                for f in sk["plain"]["fields"]:
                    self.field(f, path)
            elif "tuple" in sk:
                for n, f in enumerate(sk["tuple"]):
                    if f is not None:
                        fi = self.item(f)
                        self.add("pub " + path + "::" + str(n) + ": " + ty(fi["inner"]["struct_field"]))
            self.impls(inner["impls"], path)
        elif kind == "enum":
            self.add("pub enum " + path + generics(inner["generics"]))
            for v in inner["variants"]:
                vi = self.item(v)
                self.add("pub " + path + "::" + vi["name"])
                vk = vi["inner"]["variant"]["kind"]
                if isinstance(vk, dict) and "struct" in vk:
                    for f in vk["struct"]["fields"]:
                        self.field(f, path + "::" + vi["name"], variant=True)
                elif isinstance(vk, dict) and "tuple" in vk:
                    for n, f in enumerate(vk["tuple"]):
                        if f is not None:
                            fi = self.item(f)
                            self.add("pub " + path + "::" + vi["name"] + "::" + str(n) + ": "
                                     + ty(fi["inner"]["struct_field"]))
            self.impls(inner["impls"], path)
        elif kind == "function":
            self.add("pub " + fn_sig(path, inner))
        elif kind == "constant":
            self.add("pub const " + path + ": " + ty(inner["type"]))
        elif kind == "static":
            self.add("pub static " + path + ": " + ty(inner["type"]))
        elif kind == "type_alias":
            self.add("pub type " + path + generics(inner["generics"]) + " = " + ty(inner["type"]))
        elif kind == "trait":
            self.add("pub trait " + path + generics(inner["generics"]))
            for m in inner["items"]:
                mi = self.item(m)
                (mk, minner), = mi["inner"].items()
                if mk == "function":
                    self.add("pub " + fn_sig(path + "::" + mi["name"], minner))
                else:
                    self.add("pub " + mk + " " + path + "::" + mi["name"])
        elif kind == "macro":
            self.add("pub macro " + path + "!")
        else:
            self.add("pub " + kind + " " + path)

    def field(self, f, path, variant=False):
        fi = self.item(f)
        # A variant's fields are as public as the enum (rustdoc says "default").
        if fi is not None and (variant or fi["visibility"] == "public"):
            self.add("pub " + path + "::" + fi["name"] + ": " + ty(fi["inner"]["struct_field"]))

    def impls(self, impls, path):
        traits = []
        for i in impls:
            ii = self.item(i)
            if ii is None:
                continue
            imp = ii["inner"]["impl"]
            if imp.get("trait") is None:
                for m in imp["items"]:
                    mi = self.item(m)
                    if mi is None or mi["visibility"] != "public":
                        continue
                    (mk, minner), = mi["inner"].items()
                    if mk == "function":
                        self.add("pub " + fn_sig(path + "::" + mi["name"], minner))
                    elif mk in ("assoc_const", "constant"):
                        t = minner.get("type")
                        self.add("pub const " + path + "::" + mi["name"] + ": " + ty(t))
                    else:
                        self.add("pub " + mk + " " + path + "::" + mi["name"])
            elif (not imp.get("is_synthetic") and imp.get("blanket_impl") is None
                  and imp["trait"]["path"] not in ("StructuralPartialEq",)):
                traits.append(imp["trait"]["path"] + args(imp["trait"].get("args")))
        if traits:
            self.add("impl " + ", ".join(sorted(set(traits))) + " for " + path, counted=False)


def main():
    doc = json.load(open(sys.argv[1]))
    root = doc["index"].get(str(doc["root"])) or doc["index"][doc["root"]]
    lister = Lister(doc)
    lister.module(root, root["name"])
    for line in sorted(lister.lines):
        print(line)
    print(f"# {lister.items} public items (trait impls not counted)")


if __name__ == "__main__":
    main()
