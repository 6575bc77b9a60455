"""Shape readers (JSON, raster, SVG) and the decomposition plot of the 2D method."""

import json
from pathlib import Path

import numpy as np
import pytest
import shapely
from PIL import Image

from recon.errors import ExportError, InputError
from recon.skeleton2d import Part2D, SegmentGraph, Shape2D, Skeleton2D, SkeletonResult
from recon.skeleton2d._plot import KIND_COLORS, plot_decomposition
from recon.skeleton2d._readers import MIN_SPECK_AREA, load_shape, shape_from_curves, shape_from_mask

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "shapes"


def shape_area(shape: Shape2D) -> float:
    """Area by even-odd nesting of the curves."""
    polys = [shapely.Polygon(c) for c in shape.curves]
    total = 0.0
    for i, p in enumerate(polys):
        depth = sum(q.contains(shapely.Point(shape.curves[i][0])) for j, q in enumerate(polys) if j != i)
        total += p.area if depth % 2 == 0 else -p.area
    return total


# --- JSON ---------------------------------------------------------------------------------------


def test_json_round_trip_keeps_points_and_drops_repeated_closing_point(tmp_path):
    square = [[0, 0], [2, 0], [2, 2], [0, 2]]
    hole = [[0.5, 0.5], [1, 0.5], [1, 1], [0.5, 0.5]]  # closing point repeated
    f = tmp_path / "s.json"
    f.write_text(json.dumps({"curves": [square, hole]}))
    shape = load_shape(f)
    assert len(shape.curves) == 2
    np.testing.assert_array_equal(shape.curves[0], square)
    assert len(shape.curves[1]) == 3
    assert shape_area(shape) == pytest.approx(4.0 - 0.125)


def test_star_fixture_has_the_area_of_a_five_pointed_star():
    shape = load_shape(FIXTURES / "star.json")
    # Ten triangles (centre, outer tip, inner vertex): 10 * 0.5 * R * r * sin(36°), R = 100, r = 40.
    expected = 10 * 0.5 * 100 * 40 * np.sin(np.pi / 5)
    assert shape_area(shape) == pytest.approx(expected, rel=1e-5)


# --- raster -------------------------------------------------------------------------------------


def test_raster_rectangle_contour_is_exact_and_y_points_up():
    mask = np.zeros((40, 50), bool)
    mask[5:25, 10:40] = True  # rows 5..24 (top of the image), columns 10..39
    shape = shape_from_mask(mask)
    assert len(shape.curves) == 1
    # Level-0.5 contour of a w x h block: the rectangle half a pixel out, minus four corner triangles of 1/8.
    assert shape_area(shape) == pytest.approx(30 * 20 - 0.5)
    (xmin, ymin), (xmax, ymax) = shape.bounds
    assert (xmin, xmax) == (9.5, 39.5)
    # y = (h - 1) - row: rows 5..24 become y = 34..15, so the block sits in the upper half.
    assert (ymin, ymax) == (14.5, 34.5)


def test_raster_hole_area_equals_pixel_count():
    mask = np.zeros((30, 30), bool)
    mask[3:27, 3:27] = True
    mask[10:20, 12:18] = False
    shape = shape_from_mask(mask)
    assert len(shape.curves) == 2
    # Outer contour loses 1/2 at its corners, the hole's contour gives back 1/2 at its corners.
    assert shape_area(shape) == pytest.approx(mask.sum())


def test_raster_specks_are_dropped_and_invert_swaps():
    mask = np.zeros((30, 30), bool)
    mask[5:25, 5:25] = True
    mask[15, 15] = False  # pin hole: contour area 0.5 px^2
    mask[1, 28] = True  # isolated speck
    shape = shape_from_mask(mask)
    assert len(shape.curves) == 1
    assert shape_area(shape) == pytest.approx(400 - 0.5)
    inv = shape_from_mask(mask, invert=True)
    # Inverted: the padded frame region (all background outside the block) minus the specks.
    assert len(inv.curves) == 2  # outer frame and the block as its hole; the pin hole becomes a speck, dropped
    assert MIN_SPECK_AREA > 0.5


def test_diagonal_pixel_chain_stays_one_curve():
    mask = np.zeros((20, 20), bool)
    mask[2:8, 2:8] = True
    mask[12:18, 12:18] = True
    for i in range(8, 12):
        mask[i, i] = True
    shape = shape_from_mask(mask)
    assert len(shape.curves) == 1


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_contour_tracer_matches_skimage_find_contours(seed):
    """Differential: recon's boundary-cell tracer against skimage's find_contours on random pixels."""
    from skimage.measure import find_contours

    from recon.skeleton2d._readers import _level_half_contours

    rng = np.random.default_rng(seed)
    mask = rng.random((50, 70)) < 0.45
    mask[10:40, 20:60] |= rng.random((30, 40)) < 0.9  # a large blob with pin holes next to the noise
    ours = _level_half_contours(mask)
    ref = [c[:-1] for c in find_contours(np.pad(mask, 1).astype(float), 0.5, fully_connected="high")]

    def key(c):  # the curve as a point set, and its absolute area (which needs the right point order)
        pts = tuple(sorted(map(tuple, np.round(c * 2).astype(int).tolist())))
        x, y = c[:, 1], c[:, 0]
        return pts, round(abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))) / 2, 6)

    assert len(ours) == len(ref) > 50
    assert sorted(map(key, ours)) == sorted(map(key, ref))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_traced_curves_pass_full_validation_even_on_salt_and_pepper(seed):
    """shape_from_mask skips the shapely checks because marching squares cannot make crossing curves: check it
    on random pixels, where every kind of saddle and diagonal contact occurs."""
    mask = np.random.default_rng(seed).random((60, 60)) < 0.5
    shape = shape_from_mask(mask)
    assert len(shape.curves) > 10
    again = shape_from_curves(list(shape.curves))  # raises InputError on any crossing or touching
    assert len(again.curves) == len(shape.curves)


@pytest.mark.parametrize(
    "mode",
    ["L01", "L255", "P01", "RGB", "RGBA_alpha", "1", "CMYK_tif", "LA_alpha"],
)
def test_image_encodings_give_the_same_shape(tmp_path, mode):
    mask = np.zeros((24, 32), bool)
    mask[4:20, 6:26] = True
    mask[9:14, 12:18] = False
    f = tmp_path / "m.png"
    if mode == "L01":
        Image.fromarray(mask.astype(np.uint8)).save(f)
    elif mode == "L255":
        Image.fromarray(mask.astype(np.uint8) * 255).save(f)
    elif mode == "P01":  # MPEG-7 style: palette image, indices 0/1
        im = Image.fromarray(mask.astype(np.uint8), mode="L").convert("P")
        im.putpalette([0, 0, 0, 255, 255, 255] + [0] * 762)
        im.save(f)
    elif mode == "RGB":
        rgb = np.where(mask[..., None], [250, 240, 230], [10, 20, 30]).astype(np.uint8)
        Image.fromarray(rgb).save(f)
    elif mode == "RGBA_alpha":  # colour says nothing (all black), alpha carries the silhouette
        rgba = np.zeros((*mask.shape, 4), np.uint8)
        rgba[..., 3] = mask * 255
        Image.fromarray(rgba).save(f)
    elif mode == "CMYK_tif":
        f = tmp_path / "m.tif"
        rgb = np.where(mask[..., None], [255, 255, 255], [0, 0, 0]).astype(np.uint8)
        Image.fromarray(rgb).convert("CMYK").save(f)
    elif mode == "LA_alpha":
        la = np.zeros((*mask.shape, 2), np.uint8)
        la[..., 1] = mask * 255
        Image.fromarray(la, mode="LA").save(f)
    else:
        Image.fromarray(mask).convert("1").save(f)
    shape = load_shape(f)
    assert len(shape.curves) == 2
    assert shape_area(shape) == pytest.approx(mask.sum())


def test_bundled_png_has_one_hole():
    shape = load_shape(FIXTURES / "wrench.png")
    mask = np.asarray(Image.open(FIXTURES / "wrench.png")) > 0
    assert len(shape.curves) == 2
    # Marching squares cuts each convex corner and fills each concave one by 1/8 px^2: within 1% of the pixel count.
    assert shape_area(shape) == pytest.approx(mask.sum(), rel=0.01)


# --- SVG ----------------------------------------------------------------------------------------


def test_svg_circle_rect_and_transform(tmp_path):
    f = tmp_path / "s.svg"
    f.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="300" height="200">'
        '<g transform="translate(100,0)"><rect x="0" y="0" width="100" height="80"/></g>'
        '<circle cx="150" cy="40" r="25"/>'
        '<path d="M 0 150 L 50 150" stroke="black"/>'  # open: ignored
        "</svg>"
    )
    shape = load_shape(f)
    assert len(shape.curves) == 2
    assert shape_area(shape) == pytest.approx(100 * 80 - np.pi * 25**2, rel=1e-5)
    (xmin, ymin), (xmax, ymax) = shape.bounds
    # translate applied; y flipped so that SVG's top (y = 0) is the highest point.
    assert (xmin, xmax) == pytest.approx((100.0, 200.0))
    assert (ymin, ymax) == pytest.approx((-80.0, 0.0))


def test_bundled_svg_area():
    shape = load_shape(FIXTURES / "bracket.svg")
    assert len(shape.curves) == 4
    areas = sorted(shapely.Polygon(c).area for c in shape.curves)
    # Holes: two circles r = 12 and an 80 x 16 slot with rounded ends (rx = 8).
    assert sum(areas[:3]) == pytest.approx(2 * np.pi * 12**2 + (80 * 16 - (4 - np.pi) * 8**2), rel=1e-4)
    # Plate: 200 x 100, three corners rounded (r = 20), a V notch of 40 x 20, and the corner a cubic cuts off,
    # that last one measured on an independent dense Bernstein evaluation of the cubic.
    t = np.linspace(0, 1, 20001)[:, None]
    ctrl = np.array([[200, 80], [200, 95], [190, 100], [175, 100]], float)
    bez = (1 - t) ** 3 * ctrl[0] + 3 * (1 - t) ** 2 * t * ctrl[1] + 3 * (1 - t) * t**2 * ctrl[2] + t**3 * ctrl[3]
    cubic_corner = shapely.Polygon(np.vstack([bez, [[200, 100]]])).area
    plate = 200 * 100 - 3 * (20**2 - np.pi * 20**2 / 4) - 0.5 * 40 * 20 - cubic_corner
    assert areas[3] == pytest.approx(plate, rel=1e-4)
    assert shape_area(shape) == pytest.approx(areas[3] - sum(areas[:3]), rel=1e-12)


# --- validation ---------------------------------------------------------------------------------


def _json(tmp_path, curves):
    f = tmp_path / "c.json"
    f.write_text(json.dumps({"curves": curves}))
    return f


@pytest.mark.parametrize(
    "curves, message",
    [
        ([], "no curves"),
        ([[[0, 0], [1, 1], [0, 0]]], "distinct points"),
        ([[[0, 0], [1, 0], [2, 0]]], "no area"),
        ([[[0, 0], [1, 0], [float("nan"), 1]]], "NaN"),
        ([[[0, 0], [4, 2], [4, 0], [0, 3]]], "intersects itself"),
        ([[[0, 0], [2, 0], [2, 2], [0, 2]], [[1, 1], [3, 1], [3, 3], [1, 3]]], "curves 0 and 1 intersect"),
        ([[[0, 0], [2, 0], [2, 2], [0, 2]], [[2, 0], [3, 0], [3, 1]]], "intersect or touch"),
        ([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], "expected (k, 2)"),
        ([[[0, 0], [1], [0, 1]]], "not a list of [x, y] numbers"),
    ],
)
def test_bad_curves_raise_one_line_input_error(tmp_path, curves, message):
    f = _json(tmp_path, curves)
    with pytest.raises(InputError) as exc:
        load_shape(f)
    text = str(exc.value)
    assert message in text and str(f) in text and "\n" not in text


@pytest.mark.parametrize(
    "name, content, message",
    [
        ("missing.json", None, "does not exist"),
        ("empty.json", b"", "is empty"),
        ("bad.json", b"{curves:", "not valid JSON"),
        ("list.json", b"[1, 2]", "expected an object"),
        ("shape.dxf", b"0\nSECTION", "unknown suffix"),
        ("garbage.png", b"not an image at all", "cannot read image"),
        ("open.svg", b'<svg xmlns="http://www.w3.org/2000/svg"><path d="M0 0 L10 10"/></svg>', "no closed paths"),
        ("broken.svg", b"<svg <<", "cannot read SVG"),
    ],
)
def test_bad_files_raise_one_line_input_error(tmp_path, name, content, message):
    f = tmp_path / name
    if content is not None:
        f.write_bytes(content)
    with pytest.raises(InputError) as exc:
        load_shape(f)
    assert message in str(exc.value) and "\n" not in str(exc.value)


def test_black_image_has_no_shape(tmp_path):
    f = tmp_path / "black.png"
    Image.fromarray(np.zeros((10, 10), np.uint8)).save(f)
    with pytest.raises(InputError, match="no foreground"):
        load_shape(f)
    with pytest.raises(InputError, match="invert applies to raster"):
        load_shape(FIXTURES / "star.json", invert=True)


def test_shape_from_curves_accepts_arrays_and_rejects_none():
    shape = shape_from_curves([np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])])
    assert shape.curves[0].dtype == np.float64 and shape.curves[0].shape == (3, 2)
    with pytest.raises(InputError, match="no curves"):
        shape_from_curves(None)


# --- plot ---------------------------------------------------------------------------------------


def bar_result(kinds=("terminal", "linear", "terminal")) -> SkeletonResult:
    """A hand-built decomposition of the rectangle [0, 4] x [0, 1]: parts of areas 1, 2, 1."""
    xs = [0.0, 1.0, 3.0, 4.0]
    points = np.array([[x, 0.0] for x in xs] + [[x, 1.0] for x in xs[::-1]])
    boxes = [(0.0, 1.0), (1.0, 3.0), (3.0, 4.0)]
    parts = tuple(
        Part2D(
            kind=k,
            polygon=np.array([[a, 0.0], [b, 0.0], [b, 1.0], [a, 1.0]]),
            holes=(),
            skeleton_vertices=np.array([i], np.int64),
            skeleton_edges=np.zeros(0, np.int64),
            boundary_segments=np.zeros((0, 2), np.int64),
        )
        for i, (k, (a, b)) in enumerate(zip(kinds, boxes))
    )
    skel = Skeleton2D(
        vertices=np.array([[0.5, 0.5], [1.0, 0.5], [2.0, 0.5], [3.0, 0.5], [3.5, 0.5]]),
        radius=np.full(5, 0.5),
        edges=np.array([[0, 1], [1, 2], [2, 3], [3, 4]]),
    )
    graph = SegmentGraph(edges=np.array([[0, 1], [1, 2]]), bridges=np.array([0, 3]), separators=np.array([[1, 6], [2, 5]]))
    return SkeletonResult(
        points=points,
        curve=np.zeros(len(points), np.int64),
        potential=np.zeros(len(points)),
        curve_length=np.array([10.0]),
        skeleton=skel,
        parts=parts,
        segment_graph=graph,
        omega_min=1.0,
        spacing=1.0,
    )


def _colour_counts(png: Path) -> dict:
    rgb = np.asarray(Image.open(png).convert("RGB")).astype(int)
    out = {}
    for kind, hexcol in KIND_COLORS.items():
        target = np.array([int(hexcol[i : i + 2], 16) for i in (1, 3, 5)])
        out[kind] = int((np.abs(rgb - target).sum(axis=2) <= 6).sum())
    return out


def test_plot_colours_parts_by_kind_in_proportion_to_area(tmp_path):
    png = tmp_path / "bar.png"
    plot_decomposition(bar_result(), path=png)
    counts = _colour_counts(png)
    assert counts["junction"] == 0
    # Two terminals of area 1 each and one linear part of area 2: equal coloured areas (less the drawn lines).
    assert counts["terminal"] > 1000
    assert counts["linear"] / counts["terminal"] == pytest.approx(1.0, rel=0.1)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bar.png"]  # no temporary left behind


def test_plot_draws_on_given_axes():
    from matplotlib.figure import Figure
    from matplotlib.patches import PathPatch

    ax = Figure().add_subplot()
    out = plot_decomposition(bar_result(("junction", "linear", "terminal")), ax=ax)
    assert out is ax
    patches = [p for p in ax.patches if isinstance(p, PathPatch)]
    assert len(patches) == 1 + 3  # the shape underneath and one patch per part
    assert ax.get_aspect() == 1.0 and not ax.axison


def test_plot_into_missing_folder_raises_and_leaves_nothing(tmp_path):
    with pytest.raises(ExportError, match="does not exist"):
        plot_decomposition(bar_result(), path=tmp_path / "nope" / "p.png")
    assert list(tmp_path.iterdir()) == []
