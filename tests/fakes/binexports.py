"""Exported symbol names of PE32+ DLLs and 64-bit Mach-O dylibs, read with the standard library only.

Small readers for the tests of the native FMUs' win64 and darwin64 binaries (no llvm-objdump needed):
PE: the export directory's name table (Microsoft PE/COFF specification, "The .edata Section");
Mach-O: external symbols defined in a section, from LC_SYMTAB (mach-o/loader.h, mach-o/nlist.h).
"""

from __future__ import annotations

import struct

PE32_PLUS = 0x20B
IMAGE_FILE_DLL = 0x2000
IMAGE_FILE_MACHINE_AMD64 = 0x8664
MH_MAGIC_64 = 0xFEEDFACF
MH_DYLIB = 6
CPU_TYPE_X86_64 = 0x01000007
LC_SYMTAB = 0x2
N_EXT, N_TYPE, N_SECT = 0x01, 0x0E, 0x0E


class BinaryFormatError(ValueError):
    """The bytes are not the expected kind of binary."""


def _cstr(data: bytes, off: int) -> str:
    return data[off:data.index(b"\0", off)].decode()


def pe_exports(data: bytes) -> tuple[dict[str, int | bool], list[str]]:
    """(header facts, exported names) of a PE image; raises BinaryFormatError if it is not one."""
    if data[:2] != b"MZ":
        raise BinaryFormatError("no MZ header")
    pe = struct.unpack_from("<I", data, 0x3C)[0]
    if data[pe:pe + 4] != b"PE\0\0":
        raise BinaryFormatError("no PE signature")
    machine, nsec, _, _, _, opt_size, chars = struct.unpack_from("<HHIIIHH", data, pe + 4)
    opt = pe + 24
    magic = struct.unpack_from("<H", data, opt)[0]
    facts = {"machine": machine, "pe32_plus": magic == PE32_PLUS, "dll": bool(chars & IMAGE_FILE_DLL)}
    if magic != PE32_PLUS:
        return facts, []
    export_rva, export_size = struct.unpack_from("<II", data, opt + 112)
    sections = []
    for i in range(nsec):
        s = opt + opt_size + 40 * i
        vsize, vaddr, raw_size, raw_ptr = struct.unpack_from("<IIII", data, s + 8)
        sections.append((vaddr, max(vsize, raw_size), raw_ptr))

    def off(rva: int) -> int:
        for vaddr, size, raw in sections:
            if vaddr <= rva < vaddr + size:
                return rva - vaddr + raw
        raise BinaryFormatError(f"RVA {rva:#x} in no section")

    if export_size == 0:
        return facts, []
    d = off(export_rva)
    n_names = struct.unpack_from("<I", data, d + 24)[0]
    names_rva = struct.unpack_from("<I", data, d + 32)[0]
    names = [_cstr(data, off(struct.unpack_from("<I", data, off(names_rva) + 4 * i)[0])) for i in range(n_names)]
    return facts, names


def macho_exports(data: bytes) -> tuple[dict[str, int | bool], list[str]]:
    """(header facts, exported names without the leading underscore) of a 64-bit Mach-O image."""
    magic, cputype, _, filetype, ncmds, _, _, _ = struct.unpack_from("<IiiIIIII", data, 0)
    if magic != MH_MAGIC_64:
        raise BinaryFormatError(f"Mach-O magic {magic:#x} is not MH_MAGIC_64")
    facts = {"cputype": cputype, "dylib": filetype == MH_DYLIB}
    pos = 32
    names: list[str] = []
    for _ in range(ncmds):
        cmd, size = struct.unpack_from("<II", data, pos)
        if cmd == LC_SYMTAB:
            symoff, nsyms, stroff, _ = struct.unpack_from("<IIII", data, pos + 8)
            for i in range(nsyms):
                strx, ntype, _, _, _ = struct.unpack_from("<IBBhQ", data, symoff + 16 * i)
                if ntype & N_EXT and (ntype & N_TYPE) == N_SECT:
                    name = _cstr(data, stroff + strx)
                    names.append(name[1:] if name.startswith("_") else name)
        pos += size
    return facts, names
