"""Pascal VOC xml labels: one ``.xml`` file per picture::

    <annotation>
      <filename>foggy-001.jpg</filename>
      <size><width>1280</width><height>675</height><depth>3</depth></size>
      <object>
        <name>car</name> <difficult>0</difficult>
        <bndbox><xmin>462</xmin><ymin>467</ymin><xmax>601</xmax><ymax>598</ymax></bndbox>
      </object> ...
    </annotation>

Layout (the shared ``dawn_fog``; Pascal VOC's own ``Annotations/`` + ``JPEGImages/`` too)::

    ROOT/voc/NAME.xml          (or ROOT/Annotations/NAME.xml)
    ROOT/images/FILENAME       (or ROOT/JPEGImages/FILENAME)

The picture is ``<filename>`` in the image folder (without a ``<filename>``: the xml's name
with a picture suffix). Its size is read from the picture's header; a ``<size>`` that says
otherwise is a :class:`~fastdet.errors.DataError` (the labels are for another picture). Box
corners are taken as they are, as continuous pixel coordinates (VOC's own 1-based pixel
indices and the 0-based ones of most labelling tools differ by 1 px, below the labels'
accuracy).

Class names are read by :func:`~fastdet.labels.rules.class_kind` (car, truck, bus, van, ...
vehicles; motorcycle, bicycle ignore regions; person dropped; an unknown name is a
DataError); ``<difficult>1</difficult>`` makes any vehicle an ignore region; then the rules of
:mod:`fastdet.labels.rules`. Errors name the file and the line.

Safety: the xml is parsed by expat without a DTD: a file with a ``<!DOCTYPE`` or an
``<!ENTITY`` declaration is refused (entity expansion is the classic XML attack:
"billion laughs", external files), so no dependency such as defusedxml is needed.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from xml.parsers import expat

from ..errors import DataError
from ..io.files import read_input_bytes
from .imagesize import IMAGE_SUFFIXES, image_size
from .picture import AnnotatedPicture
from .rules import Box, camera_for, check_folder, class_kind, make_picture, not_empty, number, picture_in


@dataclass(frozen=True)
class Node:
    """An xml element as read: tag, the line it starts on, text (stripped), children."""

    tag: str
    line: int
    text: str = ""
    children: tuple[Node, ...] = ()

    def find(self, tag: str) -> Node | None:
        """The first child named ``tag``."""
        return next((c for c in self.children if c.tag == tag), None)

    def findall(self, tag: str) -> list[Node]:
        """Every child named ``tag``."""
        return [c for c in self.children if c.tag == tag]


class _Refused(Exception):
    pass


def parse_xml(data: bytes, source: str) -> Node:
    """The root element of the xml document ``data``; DataError naming ``source`` (and the
    line) for xml that is not well formed, or that declares a DTD or entities."""
    parser = expat.ParserCreate()
    # open elements: (tag, line, text pieces, finished children)
    stack: list[tuple[str, int, list[str], list[Node]]] = []
    root: list[Node] = []

    def start(tag: str, _attrs: dict[str, str]) -> None:
        stack.append((tag, parser.CurrentLineNumber, [], []))

    def end(_tag: str) -> None:
        tag, line, text, children = stack.pop()
        node = Node(tag, line, "".join(text).strip(), tuple(children))
        (stack[-1][3] if stack else root).append(node)

    def chars(data: str) -> None:
        if stack:
            stack[-1][2].append(data)

    def refuse(*_args: object) -> None:
        raise _Refused()

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = chars
    parser.StartDoctypeDeclHandler = refuse
    parser.EntityDeclHandler = refuse
    parser.UnparsedEntityDeclHandler = refuse
    parser.ExternalEntityRefHandler = refuse  # type: ignore[assignment]
    try:
        parser.Parse(data, True)
    except _Refused:
        raise DataError(f"{source}: line {parser.CurrentLineNumber}: a DTD or entity declaration "
                        f"(<!DOCTYPE / <!ENTITY): refused, label files need neither") from None
    except expat.ExpatError as exc:
        raise DataError(f"{source}: line {exc.lineno}: not well-formed xml "
                        f"({expat.ErrorString(exc.code)})") from None
    return root[0]


def _child_number(node: Node, tag: str, source: str) -> float:
    child = node.find(tag)
    if child is None:
        raise DataError(f"{source}: line {node.line}: <{node.tag}> has no <{tag}>")
    return number(child.text, f"<{tag}>", f"{source}: line {child.line}")


def parse_voc(data: bytes, source: str) -> tuple[str | None, tuple[int, int, int] | None, list[Box]]:
    """One VOC file's ``(filename or None, (width, height, line) of <size> or None, boxes)``;
    the boxes in the file's pixels, dropped classes left out. ``source`` names the file in
    errors."""
    root = parse_xml(data, source)
    if root.tag != "annotation":
        raise DataError(f"{source}: line {root.line}: expected a Pascal VOC <annotation>, got <{root.tag}>")
    fn = root.find("filename")
    filename = fn.text if fn is not None and fn.text else None
    size = None
    sz = root.find("size")
    if sz is not None:
        w, h = _child_number(sz, "width", source), _child_number(sz, "height", source)
        if w > 0 and h > 0:  # some tools write 0 for "unknown"
            size = (int(w), int(h), sz.line)
    boxes = []
    for obj in root.findall("object"):
        where = f"{source}: line {obj.line}"
        name = obj.find("name")
        if name is None or not name.text:
            raise DataError(f"{where}: <object> has no <name>")
        kind = class_kind(name.text, f"{source}: line {name.line}")
        bb = obj.find("bndbox")
        if bb is None:
            raise DataError(f"{where}: <object> has no <bndbox>")
        x1, y1, x2, y2 = (_child_number(bb, t, source) for t in ("xmin", "ymin", "xmax", "ymax"))
        difficult = obj.find("difficult")
        hard = difficult is not None and difficult.text not in ("", "0")
        if kind is None:
            continue
        boxes.append(Box(x1, y1, x2, y2, kind and not hard, where))
    return filename, size, boxes


def _folders(root: Path) -> tuple[Path, Path]:
    for xml_name, img_name in (("voc", "images"), ("Annotations", "JPEGImages")):
        if (root / xml_name).is_dir():
            return root / xml_name, check_folder(root / img_name, "images")
    raise DataError(f"{root}: no voc/ (or Annotations/) folder of Pascal VOC xml files")


def _image_for(xml: Path, filename: str | None, images: Path) -> Path:
    if filename is not None:
        p = picture_in(images, filename, str(xml), f"<filename>{filename}</filename>")
        if p.is_file():
            return p
        raise DataError(f"{xml}: the picture {p} is not there (<filename>{filename}</filename>)")
    for suffix in IMAGE_SUFFIXES:
        for cand in (images / (xml.stem + suffix), images / (xml.stem + suffix.upper())):
            if cand.is_file():
                return cand
    raise DataError(f"{xml}: no picture {images / xml.stem}.* for this label file")


def read_voc(root: str | Path, *, source: str | None = None, camera: str | Callable[[str], str] | None = None,
             complete: bool = True) -> list[AnnotatedPicture]:
    """Every picture of the Pascal VOC set at ``root`` (layout in the module docstring), in
    the order of the sorted xml names; ``source``, ``camera``, ``complete`` as
    :func:`~fastdet.labels.yolo.read_yolo`'s (the picture's name is its file name). Raises
    DataError on the first error of the whole set."""
    root = check_folder(Path(root), "Pascal VOC set")
    source = source or root.name
    xml_dir, images = _folders(root)
    pictures = []
    for xml in sorted(xml_dir.glob("*.xml")):
        data = read_input_bytes(xml, "VOC xml file", text=True)
        filename, size, boxes = parse_voc(data, str(xml))
        path = _image_for(xml, filename, images)
        width, height = image_size(path)
        if size is not None and size[:2] != (width, height):
            raise DataError(f"{xml}: line {size[2]}: <size> says {size[0]}x{size[1]}, the picture {path.name} "
                            f"is {width}x{height}")
        name = path.relative_to(images).as_posix()
        pictures.append(make_picture(source=source, camera=camera_for(camera, source, name), name=name,
                                     path=path, width=width, height=height, boxes=boxes, complete=complete))
    return not_empty(pictures, xml_dir, "Pascal VOC xml files")


__all__ = ["read_voc", "parse_voc", "parse_xml", "Node"]
