"""What the page's wasm is made of, by the function names the linker leaves in it (run on the `web` profile's
output before wasm-bindgen and wasm-opt drop the names):

    cargo build --locked --profile web --target wasm32-unknown-unknown --bin meshvox   # the WebGPU build
    python3 web/wasm_sizes.py target/wasm32-unknown-unknown/web/meshvox.wasm [TOP]
(web/build.sh builds the WebGL2 build last, into the same file.)

Prints the sections' sizes, the code's bytes by crate (the first path segment of each function's mangled name; a
generic function counts where it was defined, whatever crate instantiated it) and the largest functions. Used for
docs/viewer.md's account of the page's size (issue 70); no tool beyond Python is needed.
"""

import collections
import re
import sys
import zlib


def leb(data, i):
    value = shift = 0
    while True:
        byte = data[i]
        i += 1
        value |= (byte & 0x7F) << shift
        shift += 7
        if byte < 0x80:
            return value, i


def crate_of(name):
    """The crate a mangled Rust name (legacy `_ZN...` or v0 `_R...`) belongs to."""
    if name.startswith("_ZN"):
        m = re.match(r"_ZN(\d+)", name)
        ident = name[m.end():m.end() + int(m.group(1))]
        if ident.startswith("_$LT$"):  # <T as Trait>::f: the type's crate
            inner = ident[5:].replace("$RF$", "").replace("mut$u20$", "").replace("dyn$u20$", "")
            return re.split(r"\.\.|\$", inner)[0] or ident[:20]
        return ident
    if name.startswith("_R"):
        m = re.search(r"Cs[0-9A-Za-z]*_(\d+)", name)
        if m:
            return name[m.end():m.end() + int(m.group(1))]
    return name.split("::")[0][:30]


def parse(data):
    """The sections, the function names (the name section), and each defined function's body size."""
    i, sections, names, bodies, imported = 8, [], {}, [], 0
    while i < len(data):
        section, (size, j) = data[i], leb(data, i + 1)
        end = j + size
        if section == 0:
            length, k = leb(data, j)
            name = data[k:k + length].decode()
            sections.append((f"custom {name}", size))
            k += length
            while name == "name" and k < end:
                sub, (sub_size, k2) = data[k], leb(data, k + 1)
                if sub == 1:
                    count, k3 = leb(data, k2)
                    for _ in range(count):
                        index, k3 = leb(data, k3)
                        length, k3 = leb(data, k3)
                        names[index] = data[k3:k3 + length].decode("utf8", "replace")
                        k3 += length
                k = k2 + sub_size
        else:
            sections.append((section, size))
            if section == 2:  # imports: functions among them shift the defined functions' indices
                count, k = leb(data, j)
                for _ in range(count):
                    for _ in range(2):
                        length, k = leb(data, k)
                        k += length
                    kind, k = data[k], k + 1
                    if kind == 0:
                        _, k = leb(data, k)
                        imported += 1
                    elif kind in (1, 2):
                        k += kind == 1
                        flags, k = leb(data, k)
                        _, k = leb(data, k)
                        if flags & 1:
                            _, k = leb(data, k)
                    elif kind == 3:
                        k += 2
            elif section == 10:
                count, k = leb(data, j)
                for f in range(count):
                    length, k2 = leb(data, k)
                    bodies.append((imported + f, length))
                    k = k2 + length
        i = end
    return sections, names, bodies


def main(path, top=30):
    data = open(path, "rb").read()
    sections, names, bodies = parse(data)
    print(f"{path}: {len(data):,} bytes, {len(zlib.compress(data, 9)):,} deflated")
    kinds = {1: "type", 2: "import", 3: "function", 7: "export", 10: "code", 11: "data"}
    for section, size in sections:
        print(f"  {kinds.get(section, section)}: {size:,}")
    crates = collections.Counter()
    for index, size in bodies:
        crates[crate_of(names.get(index, f"func{index}"))] += size
    print("  code by crate:")
    for crate, size in crates.most_common(top):
        print(f"    {size:>9,}  {crate}")
    print("  largest functions:")
    for size, name in sorted(((s, names.get(i, f"func{i}")) for i, s in bodies), reverse=True)[:top]:
        print(f"    {size:>9,}  {name[:140]}")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 30)
