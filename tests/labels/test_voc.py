"""fastdet.labels.voc: Pascal VOC xml sets (dawn_fog), safe xml, and malformed files."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fastdet.labels.voc import parse_xml, read_voc

from .synth import one_error, picture, write


def obj(name: str, box: tuple[float, float, float, float], difficult: int = 0) -> str:
    x1, y1, x2, y2 = box
    return (f"  <object>\n    <name>{name}</name>\n    <difficult>{difficult}</difficult>\n"
            f"    <bndbox><xmin>{x1}</xmin><ymin>{y1}</ymin><xmax>{x2}</xmax><ymax>{y2}</ymax></bndbox>\n"
            f"  </object>\n")


def xml(filename: str | None, objects: str, size: tuple[int, int] | None = (640, 360)) -> str:
    head = f"  <filename>{filename}</filename>\n" if filename else ""
    if size:
        head += f"  <size><width>{size[0]}</width><height>{size[1]}</height><depth>3</depth></size>\n"
    return f"<annotation>\n{head}{objects}</annotation>\n"


def voc_set(root: Path, files: dict[str, str]) -> Path:
    for stem, text in files.items():
        picture(root / "images" / f"{stem}.jpg")
        write(root / "voc" / f"{stem}.xml", text)
    return root


def test_dawn_fog_counts(data):
    root = data / "frames" / "dawn_fog"
    pics = read_voc(root)
    assert len(pics) == 156 and all(p.complete for p in pics)
    targets = sum(len(p.targets) for p in pics)
    ignores = sum(len(p.ignores) for p in pics)
    assert targets == 872 - 110  # the README: 872 vehicles, 110 under the target size
    assert ignores == 110 + 8 + 6  # ... + 8 motorcycles + 6 bicycles
    names = [o.find("name").text for f in sorted((root / "voc").glob("*.xml"))
             for o in parse_xml(f.read_bytes(), str(f)).findall("object")]
    assert sum(n in ("car", "truck", "bus") for n in names) == 872 and names.count("motorcycle") == 8
    # most are 1280 wide (not all, whatever the data README says: 115 of 156), many heights
    assert sum(p.width == 1280 for p in pics) == 115 and len({p.height for p in pics}) > 5


def test_classes_difficult_and_layouts(tmp_path):
    text = xml("a.jpg", obj("car", (10, 10, 110, 90)) + obj("van", (200, 10, 300, 90), difficult=1)
               + obj("person", (0, 0, 50, 50)) + obj("bicycle", (300, 100, 400, 200))
               + obj("truck", (600, 300, 700, 400)))
    root = voc_set(tmp_path / "s", {"a": text})
    (pic,) = read_voc(root, camera="c")
    np.testing.assert_allclose(pic.targets, [[10, 10, 110, 90], [600, 300, 640, 360]])
    np.testing.assert_allclose(pic.ignores, [[200, 10, 300, 90], [300, 100, 400, 200]])
    assert pic.name == "a.jpg" and pic.camera == "c" and pic.source == "s"
    # Pascal VOC's own layout; no <filename> and no <size>: the xml's name, the header's size
    picture(tmp_path / "v" / "JPEGImages" / "b.png", 320, 200)
    write(tmp_path / "v" / "Annotations" / "b.xml", xml(None, obj("bus", (0, 0, 100, 100)), size=None))
    (pic,) = read_voc(tmp_path / "v")
    assert (pic.width, pic.height) == (320, 200) and pic.path.name == "b.png" and len(pic.targets) == 1


def test_dtd_and_entities_are_refused(tmp_path):
    laughs = ('<?xml version="1.0"?>\n<!DOCTYPE lolz [\n <!ENTITY lol "lol">\n'
              ' <!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">\n]>\n'
              '<annotation><filename>&lol2;</filename></annotation>\n')
    root = voc_set(tmp_path / "a", {"a": laughs})
    one_error(lambda: read_voc(root), root / "voc" / "a.xml", "DTD or entity declaration", line=2)
    external = ('<?xml version="1.0"?>\n<!DOCTYPE a SYSTEM "file:///etc/passwd">\n<annotation/>\n')
    root = voc_set(tmp_path / "b", {"a": external})
    one_error(lambda: read_voc(root), root / "voc" / "a.xml", "refused", line=2)


def test_malformed_files(tmp_path):
    good = xml("ok.jpg", obj("car", (10, 10, 110, 90)))
    cases = {
        "xml": ("<annotation>\n<object>\n</annotation>\n", "not well-formed xml", 3),
        "root": ("<notes/>\n", "expected a Pascal VOC <annotation>", 1),
        "class": (xml("z.jpg", obj("car", (1, 1, 50, 50)) + obj("cra", (1, 1, 50, 50))), "unknown class 'cra'", 10),
        "number": (xml("z.jpg", obj("car", (1, 1, "4O", 50))), "<xmax> is not a number: '4O'", 7),
        "negative": (xml("z.jpg", obj("car", (100, 1, 50, 50))), "negative box size", 4),
        "outside": (xml("z.jpg", obj("car", (700, 1, 750, 50))), "entirely outside the 640x360 picture", 4),
        "nobox": (xml("z.jpg", "  <object><name>car</name></object>\n"), "<object> has no <bndbox>", 4),
        "size": (xml("z.jpg", "", size=(1280, 720)), "<size> says 1280x720, the picture z.jpg is 640x360", 3),
    }
    for name, (text, words, line) in cases.items():
        root = voc_set(tmp_path / name, {"ok": good, "z": text})
        one_error(lambda r=root: read_voc(r), root / "voc" / "z.xml", words, line=line)


def test_missing_picture_and_empty_set(tmp_path):
    root = voc_set(tmp_path / "s", {"a": xml("a.jpg", "")})
    write(root / "voc" / "b.xml", xml("b.jpg", ""))
    one_error(lambda: read_voc(root), root / "voc" / "b.xml", "b.jpg is not there")
    write(root / "voc" / "b.xml", xml(None, ""))
    one_error(lambda: read_voc(root), root / "voc" / "b.xml", "no picture")
    empty = tmp_path / "e"
    (empty / "voc").mkdir(parents=True)
    (empty / "images").mkdir()
    one_error(lambda: read_voc(empty), empty / "voc", "no Pascal VOC xml files")
    one_error(lambda: read_voc(tmp_path), tmp_path, "no voc/")


def test_a_filename_outside_the_set_is_refused(tmp_path):
    """A ``<filename>`` leading out of the picture folder (``../x.jpg``, an absolute path) named a
    picture elsewhere on the machine, which was read as the set's (issue 34); now one line naming
    the xml and the entry, whether the file is there or not."""
    outside = picture(tmp_path / "elsewhere.jpg")
    root = voc_set(tmp_path / "s", {"a": xml("a.jpg", "")})
    for name in ("../../elsewhere.jpg", str(outside), "sub/../../../elsewhere.jpg", "../../etc/x.jpg", "/etc/hostname"):
        write(root / "voc" / "b.xml", xml(name, ""))
        one_error(lambda: read_voc(root), root / "voc" / "b.xml", f"<filename>{name}</filename>",
                  "outside the set's picture folder", "labels must describe pictures of the set")
    picture(root / "images" / "sub" / "c.jpg")
    write(root / "voc" / "b.xml", xml("sub/../sub/c.jpg", ""))  # inside, however written
    assert [p.name for p in read_voc(root)] == ["a.jpg", "sub/c.jpg"]
