"""The kinds of Faiss index a task of a memory can use, one class each (`robofailring.memory.index`).

`flat` is exact (`IndexFlatIP`). `ivf_pqfs` is what `auto` picks for a large task: an inverted file
whose lists hold 4-bit product-quantisation codes of the residuals, scanned with Faiss's SIMD
fast-scan (`IndexIVFPQFastScan`), and whose top `k_factor`·k candidates are re-ranked on 8-bit
scalar codes of the full vectors (`IndexRefine` over an `IndexScalarQuantizer`): a query reads the
coarse centroids, `nprobe` lists of small codes and `k_factor`·k refine codes. `ivf_sq8`
(`IndexIVFScalarQuantizer`, one byte per dimension in the lists) is the previous default, kept so
that memories written with it load and search as before. docs/scale.md has the measurements.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Final

import faiss

from robofailring.errors import MemoryFormatError, SettingError

FLAT: Final[str] = "flat"
IVF_SQ8: Final[str] = "ivf_sq8"
IVF_PQFS: Final[str] = "ivf_pqfs"
DIMS_PER_SUBQUANTIZER: Final[int] = 16  # ivf_pqfs: one 4-bit code per 16 dimensions (64 at 1024-d)
DEFAULT_K_FACTOR: Final[int] = 64  # ivf_pqfs: candidates re-ranked per result


@dataclass(frozen=True)
class IndexSpec:
    """How one task's entries are indexed: the kind and, for the inverted files, their parameters."""

    kind: str = FLAT
    nlist: int = 0  # inverted files: k-means lists
    nprobe: int = 0  # inverted files: lists read per query
    pq_m: int = 0  # ivf_pqfs: product-quantisation sub-quantizers (4 bits each)
    k_factor: int = 0  # ivf_pqfs: candidates re-ranked per result asked for

    def __post_init__(self) -> None:
        kind_of(self.kind).check(self)

    def to_dict(self) -> dict[str, Any]:
        """The manifest's description of this index: its kind and the parameters that kind uses."""
        return {"kind": self.kind} | {name: getattr(self, name) for name in kind_of(self.kind).parameters}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> IndexSpec:
        """Parse `to_dict`'s output (MemoryFormatError on anything else)."""
        try:
            kind = kind_of(str(data["kind"]))
            return cls(kind=kind.name, **{name: int(data[name]) for name in kind.parameters})
        except (KeyError, TypeError, ValueError, SettingError) as error:
            raise MemoryFormatError(f"bad index description {dict(data)!r}: {error}") from error


class IndexKind:
    """One kind of index: how to create it, recognise it in a file, size it and search it filtered."""

    name: ClassVar[str]
    parameters: ClassVar[tuple[str, ...]] = ()
    trained: ClassVar[bool] = False  # needs k-means (and codebook) training before entries are added
    min_training: ClassVar[int] = 0  # training entries besides the lists' k-means (codebooks)

    def check(self, spec: IndexSpec) -> None:
        """SettingError when `spec`'s parameters do not fit this kind."""

    def create(self, dim: int, spec: IndexSpec) -> faiss.Index:
        raise NotImplementedError

    def spec_of(self, index: faiss.Index) -> IndexSpec | None:
        """The spec `index` was created with, or None when it is not of this kind."""
        raise NotImplementedError

    def nbytes(self, index: faiss.Index, spec: IndexSpec) -> int:
        """Bytes the index holds in RAM: codes or vectors, list ids, centroids."""
        raise NotImplementedError

    def search_parameters(self, index: Any, selector: faiss.IDSelector) -> faiss.SearchParameters:
        """Search parameters that keep only the entries `selector` accepts, the rest as stored."""
        params: Any = faiss.SearchParameters()
        params.sel = selector
        return params


class Flat(IndexKind):
    name = FLAT

    def create(self, dim: int, spec: IndexSpec) -> faiss.Index:
        return faiss.IndexFlatIP(dim)

    def spec_of(self, index: faiss.Index) -> IndexSpec | None:
        return IndexSpec(FLAT) if isinstance(index, faiss.IndexFlatIP) else None

    def nbytes(self, index: faiss.Index, spec: IndexSpec) -> int:
        return int(index.ntotal) * int(index.d) * 4


def _check_lists(spec: IndexSpec) -> None:
    # Not only a sanity check: Faiss's IndexIVF caps nprobe at nlist, its fast-scan IVF (ivf_pqfs) does not,
    # and returns garbage above it (distances of 2e31, Faiss 1.15.1; bench/bench_scale.py's sweep met it)
    if not 1 <= spec.nprobe <= spec.nlist:
        raise SettingError(
            f"{spec.kind} needs 1 <= nprobe <= nlist, got nlist {spec.nlist}, nprobe {spec.nprobe}"
        )


class IvfSq8(IndexKind):
    name = IVF_SQ8
    parameters = ("nlist", "nprobe")
    trained = True

    def check(self, spec: IndexSpec) -> None:
        _check_lists(spec)

    def create(self, dim: int, spec: IndexSpec) -> faiss.Index:
        quantizer = faiss.IndexFlatIP(dim)
        index = faiss.IndexIVFScalarQuantizer(
            quantizer, dim, spec.nlist, faiss.ScalarQuantizer.QT_8bit, faiss.METRIC_INNER_PRODUCT
        )
        index.nprobe = spec.nprobe  # Faiss's Python layer keeps the quantizer alive with the index
        return index

    def spec_of(self, index: faiss.Index) -> IndexSpec | None:
        if (
            isinstance(index, faiss.IndexIVFScalarQuantizer)
            and index.metric_type == faiss.METRIC_INNER_PRODUCT
        ):
            return IndexSpec(IVF_SQ8, nlist=int(index.nlist), nprobe=int(index.nprobe))
        return None

    def nbytes(self, index: faiss.Index, spec: IndexSpec) -> int:
        return int(index.ntotal) * (int(index.d) + 8) + spec.nlist * int(index.d) * 4  # 1 byte a dim

    def search_parameters(self, index: Any, selector: faiss.IDSelector) -> faiss.SearchParameters:
        return _ivf_parameters(index, selector)


class IvfPqFastScan(IndexKind):
    name = IVF_PQFS
    parameters = ("nlist", "nprobe", "pq_m", "k_factor")
    trained = True
    min_training = 256 * 39  # 16 codewords per sub-quantizer want 39 each; more steadies them

    def check(self, spec: IndexSpec) -> None:
        _check_lists(spec)
        if spec.pq_m < 1 or spec.k_factor < 1:
            raise SettingError(
                f"{IVF_PQFS} needs pq_m >= 1 and k_factor >= 1, got {spec.pq_m}, {spec.k_factor}"
            )

    def create(self, dim: int, spec: IndexSpec) -> faiss.Index:
        if dim % spec.pq_m:
            raise SettingError(f"{IVF_PQFS}: pq_m {spec.pq_m} does not divide the dimension {dim}")
        quantizer = faiss.IndexFlatIP(dim)
        base = faiss.IndexIVFPQFastScan(quantizer, dim, spec.nlist, spec.pq_m, 4, faiss.METRIC_INNER_PRODUCT)
        base.by_residual = True  # codes of x - centroid: finer than codes of x (S⁺ error 4× lower)
        base.nprobe = spec.nprobe
        refine = faiss.IndexScalarQuantizer(dim, faiss.ScalarQuantizer.QT_8bit, faiss.METRIC_INNER_PRODUCT)
        index = faiss.IndexRefine(base, refine)  # Faiss's Python layer keeps base and refine alive
        index.k_factor = spec.k_factor
        return index

    def spec_of(self, index: faiss.Index) -> IndexSpec | None:
        if not isinstance(index, faiss.IndexRefine) or index.metric_type != faiss.METRIC_INNER_PRODUCT:
            return None
        base = faiss.downcast_index(index.base_index)
        if not isinstance(base, faiss.IndexIVFPQFastScan) or base.nbits != 4:
            return None
        refine = faiss.downcast_index(index.refine_index)
        if (
            not isinstance(refine, faiss.IndexScalarQuantizer)
            or refine.sq.qtype != faiss.ScalarQuantizer.QT_8bit
        ):
            return None
        return IndexSpec(
            IVF_PQFS,
            nlist=int(base.nlist),
            nprobe=int(base.nprobe),
            pq_m=int(base.M),
            k_factor=int(index.k_factor),
        )

    def nbytes(self, index: faiss.Index, spec: IndexSpec) -> int:
        codes = (spec.pq_m + 1) // 2 + 8  # 4-bit codes and a list id per entry
        return int(index.ntotal) * (codes + int(index.d)) + spec.nlist * int(index.d) * 4

    def search_parameters(self, index: Any, selector: faiss.IDSelector) -> faiss.SearchParameters:
        base = _ivf_parameters(faiss.downcast_index(index.base_index), selector)
        params: Any = faiss.IndexRefineSearchParameters()
        params.k_factor = float(index.k_factor)
        params.base_index_params = base
        params.referenced_objects = [base]  # Faiss holds a bare pointer to the base parameters
        return params


def _ivf_parameters(index: Any, selector: faiss.IDSelector) -> Any:
    params: Any = faiss.SearchParametersIVF()
    params.sel = selector
    params.nprobe = int(index.nprobe)
    return params


KINDS: Final[dict[str, IndexKind]] = {kind.name: kind for kind in (Flat(), IvfSq8(), IvfPqFastScan())}


def kind_of(name: str) -> IndexKind:
    """The kind called `name` (SettingError naming the kinds otherwise)."""
    if name not in KINDS:
        raise SettingError(f"index kind must be one of {', '.join(KINDS)}, got {name!r}")
    return KINDS[name]


def spec_of(index: faiss.Index) -> IndexSpec:
    """The spec of a Faiss index read from a memory (MemoryFormatError for any other index, and for one
    whose parameters its kind refuses, e.g. nprobe above nlist)."""
    for kind in KINDS.values():
        try:
            spec = kind.spec_of(index)
        except SettingError as error:
            raise MemoryFormatError(
                f"a {kind.name} index with parameters it cannot search with: {error}"
            ) from error
        if spec is not None:
            return spec
    raise MemoryFormatError(f"unsupported Faiss index type {type(index).__name__}")


def pq_subquantizers(dim: int) -> int:
    """The most sub-quantizers of at least DIMS_PER_SUBQUANTIZER dimensions that divide `dim`."""
    count = max(1, dim // DIMS_PER_SUBQUANTIZER)
    while dim % count:
        count -= 1
    return count
