"""The picture of a plan: an SVG by our own small writer (no plotting dependency; networkx's drawing
needs matplotlib and knows nothing of lanes), titled by the program's project, setups as lanes,
workingsteps as boxes in execution order coloured by the body type of their tool (a legend names
each), in rows of a readable width, tool changes marked, rough -> finish pairs of a feature joined by
arcs (red and dashed when the finish comes first); a large plan drawn as runs of steps with one
setup and one tool, in pages (:class:`PlanPicture`). PNG needs the ``png`` extra (cairosvg)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from html import escape
from typing import TYPE_CHECKING

from stepnc_graph.workplan.model import NO_TOOL, NO_TOOL_BODY, PlanError, Step, Thing, ToolChange

if TYPE_CHECKING:
    from stepnc_graph.workplan.analyses import Plan

PALETTE = ("#4e79a7", "#f28e2b", "#59a14f", "#b07aa1", "#76b7b2", "#edc948", "#ff9da7", "#9c755f", "#bab0ac",
           "#e15759")


def _ink(fill: str) -> str:
    """Text colour readable on ``fill``: dark on light colours (relative luminance above 0.5)."""
    r, g, b = (int(fill[i:i + 2], 16) / 255 for i in (1, 3, 5))
    return "#222" if 0.2126 * r + 0.7152 * g + 0.0722 * b > 0.5 else "#fff"


@dataclass(frozen=True)
class Block:
    """Consecutive steps with one setup and one tool: one box of a summarised picture."""

    steps: tuple[Step, ...]

    @property
    def first(self) -> Step:
        return self.steps[0]

    @property
    def last(self) -> Step:
        return self.steps[-1]


def blocks(steps: list[Step]) -> list[Block]:
    """The steps cut wherever the setup or the tool changes."""
    out: list[list[Step]] = []
    for s in steps:
        if out and _block_key(out[-1][-1]) == _block_key(s):
            out[-1].append(s)
        else:
            out.append([s])
    return [Block(tuple(b)) for b in out]


def _block_key(s: Step) -> tuple[str | None, str | None]:
    return (s.setup.iri if s.setup else None, s.tool.iri if s.tool else None)


class PlanPicture:
    """An SVG of the plan that stays readable at any size: at most :data:`ROW` boxes a row.

    Titled by the plan's :attr:`Plan.title` (``<text class="title">``: the project's its_id, or the
    file name of a program without a project). Boxes are coloured by the body type of their tool
    (the class of the tool's ``its_tool_body`` as the program types it: ``general_turning_tool``,
    ``grooving_tool``, ``twist_drill``, ...); the legend below has one entry per type shown, with
    the tools of that type (``<g class="legend-type" data-type=..>``), and names steps whose tool
    has no body (:data:`NO_TOOL_BODY`) or that have no tool (:data:`NO_TOOL`).

    Up to :data:`DETAIL` workingsteps, one box per workingstep in execution order, in rows of
    :data:`ROW`; each row has one lane per setup, named by it and the workplans its steps run in;
    each box says the workingstep (its whole label, wrapped), #id and kind, the operation's class,
    the feature(s), the technology's numbers (feedrate, spindle speed, ...) and the tool, and its
    tooltip all of it uncut; tool changes marked, rough -> finish pairs of a feature joined by arcs
    (red and dashed when the finish comes first). Every workingstep box is ``<g class="workingstep"
    data-order=.. data-ref=.. data-tool=.. data-tool-body=..>``, every tool change ``<g
    class="tool-change" data-order=..>``, every rough/finish arc ``<path class="rough-finish"
    data-feature=..>`` (``precedence`` added when the finish comes first), every lane ``<g
    class="lane" data-setup=..>``, so the picture can be checked (and styled) by machine.

    Larger plans are summarised: one box per block of consecutive steps with one setup and one tool
    (``<g class="block" data-first=.. data-last=.. data-steps=.. data-setup=.. data-tool=..
    data-tool-body=..>``, ``precedence`` in its class when a finishing step in it runs before a
    roughing step on the same feature), :data:`BLOCK_ROW` a row, :data:`PAGE_BLOCKS` a page; a tool
    change is marked before the block it starts (``<g class="tool-change">``).
    """

    BOX_W, BOX_H, GAP, LANE_H, LEFT, TOP = 170, 106, 14, 150, 150, 70
    #: characters a box's line holds in :data:`BOX_W`: the label's (bold, 11 px), the others' (10 px)
    BOX_BOLD, BOX_CHARS = 20, 23
    #: at most this many boxes a row, and the most steps shown one box each (beyond: blocks)
    ROW, DETAIL = 16, 48
    #: tool body types the legend names at most, and tools named per type (the boxes name theirs)
    LEGEND, LEGEND_TOOLS, LEGEND_CHARS = 24, 4, 180
    BLOCK_W, BLOCK_H, BLOCK_ROW, PAGE_BLOCKS = 170, 64, 8, 120
    #: the fills of boxes whose tool has no body, and of boxes without a tool
    NO_BODY_FILL, NO_TOOL_FILL = "#ffffff", "#dddddd"

    def __init__(self, plan: Plan) -> None:
        self.plan = plan
        lanes: dict[str, None] = {}
        types: dict[str, int] = {}
        for s in plan.steps:
            lanes.setdefault(s.setup.label if s.setup else "(no setup)")
            if s.tool_body not in (NO_TOOL, NO_TOOL_BODY):
                types.setdefault(s.tool_body, len(types))
        self.lanes = list(lanes)
        self.lane = {name: i for i, name in enumerate(self.lanes)}
        #: tool body type -> its place in :data:`PALETTE` (in order of first use)
        self.types = types
        n = len(plan.steps)
        #: boxes a row: rows as even as they can be (13 steps: one row, 20: two of 10)
        self.row = -(-n // -(-n // self.ROW)) if n else 1

    @cached_property
    def blocks(self) -> list[Block]:
        """The plan's :func:`blocks` (counted for the pages, drawn on one)."""
        return blocks(self.plan.steps)

    @cached_property
    def tool_changes(self) -> list[ToolChange]:
        """The plan's tool changes (counted in the heading, drawn)."""
        return self.plan.tool_changes()

    def _lane_workplans(self) -> dict[str, str]:
        """Setup lane -> the workplans its steps run in (their its_id), in order of first use."""
        out: dict[str, list[str]] = {}
        for s in self.plan.steps:
            names = out.setdefault(s.setup.label if s.setup else "(no setup)", [])
            if s.workplan is not None and s.workplan.label and s.workplan.label not in names:
                names.append(s.workplan.label)
        return {lane: ", ".join(names) for lane, names in out.items()}

    def colour(self, step: Step) -> str:
        """The fill of a step's box: its tool body type's."""
        return self.type_colour(step.tool_body)

    def type_colour(self, tool_body: str) -> str:
        if tool_body == NO_TOOL:
            return self.NO_TOOL_FILL
        if tool_body == NO_TOOL_BODY:
            return self.NO_BODY_FILL
        return PALETTE[self.types[tool_body] % len(PALETTE)]

    def pages(self) -> int:
        if len(self.plan.steps) <= self.DETAIL:
            return 1
        return max(1, -(-len(self.blocks) // self.PAGE_BLOCKS))

    def render(self, page: int = 1) -> str:
        pages = self.pages()
        if not 1 <= page <= pages:
            raise PlanError(f"the picture has {pages} page(s); no page {page}")
        if len(self.plan.steps) <= self.DETAIL:
            return self.detailed()
        return self.summarised(page, pages)

    def _head(self, width: int, height: int, subtitle: str) -> list[str]:
        plan = self.plan
        if plan.projects:  # the file beside the project's name; a program without one is titled by it
            subtitle = f"{plan.file_name}: {subtitle}"
        return [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
                f'viewBox="0 0 {width} {height}" font-family="sans-serif" font-size="11">',
                f"<title>Workplan of {escape(plan.title)} ({escape(plan.program)})</title>",
                '<defs><marker id="arrow" markerWidth="8" markerHeight="8" refX="7" refY="4" orient="auto">'
                '<path d="M0,0 L8,4 L0,8 z" fill="#555"/></marker></defs>',
                f'<text class="title" x="10" y="24" font-size="15" font-weight="bold">{escape(plan.title)}</text>',
                f'<text x="10" y="44" fill="#444">{escape(subtitle)}</text>']

    def legend_entries(self, steps: list[Step] | tuple[Step, ...]) -> list[tuple[str, str]]:
        """(tool body type, the text of its legend entry) for the types of ``steps``, in order of
        first use: the type and the tools of it (at most :data:`LEGEND_TOOLS`, then how many more)."""
        tools: dict[str, dict[str, Thing]] = {}
        for s in steps:
            named = tools.setdefault(s.tool_body, {})
            if s.tool is not None:
                named.setdefault(s.tool.iri, s.tool)
        out = []
        for body, named in tools.items():
            names = [f"{t.label or '(no its_id)'} {t.ref}" for t in named.values()]
            more = len(names) - self.LEGEND_TOOLS
            listed = ", ".join(names[:self.LEGEND_TOOLS]) + (f" and {more} more" if more > 0 else "")
            text = f"{body}: {listed}" if listed else body
            out.append((body, text if len(text) <= self.LEGEND_CHARS else text[:self.LEGEND_CHARS - 1] + "\u2026"))
        return out

    def legend_height(self, steps: list[Step] | tuple[Step, ...]) -> int:
        return 24 * (min(len({s.tool_body for s in steps}), self.LEGEND + 1) + 2)

    def legend_width(self, steps: list[Step] | tuple[Step, ...]) -> int:
        """What the legend's longest entry needs (some 6.5 px a character of 11 px sans-serif)."""
        return max((42 + int(6.5 * len(text)) for _, text in self.legend_entries(steps)), default=0)

    def _legend(self, y: int, steps: list[Step] | tuple[Step, ...]) -> list[str]:
        out = [f'<text class="legend-title" x="10" y="{y + 11}" font-weight="bold">Tool body type (box colour)</text>']
        entries = self.legend_entries(steps)
        for k, (body, text) in enumerate(entries[:self.LEGEND]):
            ty = y + 24 * (k + 1)
            out.append(f'<g class="legend-type" data-type="{escape(body)}"><rect x="10" y="{ty}" width="16" height="14" '
                       f'fill="{self.type_colour(body)}" stroke="#333"/><text x="32" y="{ty + 11}">{escape(text)}'
                       "</text></g>")
        if len(entries) > self.LEGEND:
            out.append(f'<text class="legend-more" x="10" y="{y + 24 * (self.LEGEND + 1) + 11}" fill="#444">... and '
                       f"{len(entries) - self.LEGEND} more tool body types (each box names its tool)</text>")
        return out

    # -- one box per workingstep -------------------------------------------------------------------

    def row_height(self) -> int:
        return len(self.lanes) * self.LANE_H + 30

    def x(self, index: int) -> int:
        return self.LEFT + (index % self.row) * (self.BOX_W + self.GAP)

    def y(self, index: int, step: Step) -> int:
        lane = self.lane[step.setup.label if step.setup else "(no setup)"]
        return self.TOP + (index // self.row) * self.row_height() + lane * self.LANE_H + 20

    def detailed(self) -> str:
        steps = self.plan.steps
        index = {s.order: i for i, s in enumerate(steps)}
        rows = max(1, -(-len(steps) // self.row))
        width = self.x(min(len(steps), self.row) - 1) + self.BOX_W + 40 if steps else self.LEFT + 40
        width = max(width, self.legend_width(steps))
        legend_y = self.TOP + rows * self.row_height()
        height = legend_y + self.legend_height(steps)
        out = self._head(width, height, f"{len(steps)} workingsteps, {len(self.tool_changes)} tool changes, "
                                        f"{len(self.lanes)} setup(s); arcs join roughing and finishing on a feature")
        plans = self._lane_workplans()
        for r in range(rows):
            for i, lane in enumerate(self.lanes):
                top = self.TOP + r * self.row_height() + i * self.LANE_H
                names = "".join(f'<text x="10" y="{top + self.LANE_H // 2 + 14 * (k + 1)}" fill="#444">{escape(t)}'
                                "</text>" for k, t in enumerate(_wrap(plans.get(lane, ""), 22, 2)) if t)
                out.append(f'<g class="lane" data-setup="{escape(lane)}" data-workplan="{escape(plans.get(lane, ""))}">'
                           f'<rect x="4" y="{top}" width="{width - 8}" '
                           f'height="{self.LANE_H - 6}" fill="{"#f7f7f7" if i % 2 == 0 else "#efefef"}"/>'
                           f'<text x="10" y="{top + self.LANE_H // 2}" font-weight="bold">{escape(lane)}</text>{names}</g>')
        for k, (a, b) in enumerate(zip(steps, steps[1:], strict=False)):
            x1, y1 = self.x(k) + self.BOX_W, self.y(k, a) + self.BOX_H // 2
            x2, y2 = self.x(k + 1), self.y(k + 1, b) + self.BOX_H // 2
            if (k + 1) % self.row:
                out.append(f'<line class="sequence" x1="{x1}" y1="{y1}" x2="{x2 - 2}" y2="{y2}" stroke="#555" '
                           f'marker-end="url(#arrow)"/>')
            else:  # the next row: down the right margin, back to its start
                bottom = self.TOP + (k // self.row + 1) * self.row_height() - 12
                out.append(f'<polyline class="sequence" points="{x1},{y1} {x1 + 8},{y1} {x1 + 8},{bottom} '
                           f'{x2 - 10},{bottom} {x2 - 10},{y2} {x2 - 2},{y2}" fill="none" stroke="#555" '
                           f'marker-end="url(#arrow)"/>')
        for s in steps:
            i = index[s.order]
            out.append(self.box(s, self.x(i), self.y(i, s)))
        for change in self.tool_changes:
            i = index[change.order]
            cx, top = self.x(i) - self.GAP // 2, self.TOP + (i // self.row) * self.row_height()
            out.append(f'<g class="tool-change" data-order="{change.order}" data-from="{escape(change.before.ref)}" '
                       f'data-to="{escape(change.after.ref)}"><title>tool change before step {change.order}: '
                       f'{escape(change.before.label)} -&gt; {escape(change.after.label)}</title>'
                       f'<line x1="{cx}" y1="{top - 4}" x2="{cx}" y2="{top + self.row_height() - 24}" stroke="#d62728" '
                       f'stroke-width="2"/><text x="{cx}" y="{top - 8}" text-anchor="middle" fill="#d62728" '
                       f'font-weight="bold">T</text></g>')
        for feature, rough, finish in self.plan.rough_finish_pairs():
            i, j = index[rough], index[finish]
            x1, x2 = self.x(i) + self.BOX_W // 2, self.x(j) + self.BOX_W // 2
            y1, y2 = self.y(i, steps[i]) + self.BOX_H, self.y(j, steps[j]) + self.BOX_H
            bad = finish < rough
            dash = ' stroke-dasharray="5,3"' if bad else ""
            out.append(f'<path class="rough-finish{" precedence" if bad else ""}" data-feature="{escape(feature.ref)}" '
                       f'd="M{x1},{y1} Q{(x1 + x2) // 2},{max(y1, y2) + 26} {x2},{y2}" fill="none" '
                       f'stroke="{"#d62728" if bad else "#2c7fb8"}" stroke-width="1.5"{dash}><title>{escape(feature.label)} '
                       f'{escape(feature.ref)}: rough step {rough}, finish step {finish}</title></path>')
        out += self._legend(legend_y, steps)
        out.append("</svg>")
        return "\n".join(out) + "\n"

    def box(self, s: Step, x: int, y: int) -> str:
        """A workingstep's box: its full label (wrapped), #id and kind, the operation's class, the
        feature(s), the technology's numbers and the tool, a line each (the technology two); what
        does not fit ends in an ellipsis, and the tooltip has it all."""
        ink = _ink(self.colour(s))
        label = _wrap(f"{s.order}. {s.workingstep.label}", self.BOX_BOLD, 2)
        features = ", ".join(f"{f.label or f.cls} {f.ref}" for f in s.features)
        tool = f"{s.tool.label} {s.tool.ref}" if s.tool else NO_TOOL
        detail = [" ".join(filter(None, [s.workingstep.ref, s.kind]))]
        detail += _wrap(s.operation.cls, self.BOX_CHARS, 1) if s.operation else []
        detail += _wrap(features, self.BOX_CHARS, 1) if features else []
        detail += _wrap(s.technology.text(), self.BOX_CHARS, 2) if s.technology else []
        detail += _wrap(tool, self.BOX_CHARS, 1)
        title = (f"{s.order}. {s.workingstep.label} {s.workingstep.ref}; operation "
                 f"{s.operation.label + ' ' + s.operation.cls + ' ' + s.operation.ref if s.operation else '-'}; "
                 f"features {', '.join(f'{f.label} {f.ref} ({f.cls})' for f in s.features) or '-'}; technology "
                 f"{s.technology.ref + ' ' + s.technology.cls + ' ' + s.technology.text(', ') if s.technology else '-'}"
                 f"; tool {tool} ({s.tool_body})")
        lines = [f'<text x="{x + 6}" y="{y + 14 + 13 * k}" fill="{ink}" font-weight="bold">{escape(t)}</text>'
                 for k, t in enumerate(label)]
        lines += [f'<text x="{x + 6}" y="{y + 14 + 13 * len(label) + 12 * k}" fill="{ink}" font-size="10">'
                  f"{escape(t)}</text>" for k, t in enumerate(detail)]
        return (f'<g class="workingstep" data-order="{s.order}" data-ref="{escape(s.workingstep.ref)}" '
                f'data-tool="{escape(s.tool.ref) if s.tool else ""}" data-tool-body="{escape(s.tool_body)}">'
                f'<title>{escape(title)}</title>'
                f'<rect x="{x}" y="{y}" width="{self.BOX_W}" height="{self.BOX_H}" rx="5" fill="{self.colour(s)}" '
                f'stroke="#333"/>{"".join(lines)}</g>')

    # -- one box per block of steps with one setup and one tool -----------------------------------

    def summarised(self, page: int, pages: int) -> str:
        every = self.blocks
        shown = every[(page - 1) * self.PAGE_BLOCKS:page * self.PAGE_BLOCKS]
        starts = {b.first.order for b in shown}
        changes = [c for c in self.tool_changes if c.order in starts]
        late = {p.finish for p in self.plan.precedence_violations()}
        pitch_x, pitch_y = self.BLOCK_W + self.GAP, self.BLOCK_H + 34
        rows = -(-len(shown) // self.BLOCK_ROW)
        steps = [s for b in shown for s in b.steps]
        width = max(20 + self.BLOCK_ROW * pitch_x + 20, self.legend_width(steps))
        legend_y = self.TOP + rows * pitch_y + 20
        height = legend_y + self.legend_height(steps)
        out = self._head(width, height, f"{len(self.plan.steps)} workingsteps, {len(self.tool_changes)} tool "
                                        f"changes, {len(self.lanes)} setup(s); page {page} of {pages}: steps "
                                        f"{shown[0].first.order}-{shown[-1].last.order}, one box per run of steps "
                                        "with one setup and one tool")

        def at(k: int) -> tuple[int, int]:
            return 20 + (k % self.BLOCK_ROW) * pitch_x, self.TOP + (k // self.BLOCK_ROW) * pitch_y + 20

        for k, block in enumerate(shown):
            x, y = at(k)
            if k + 1 < len(shown):
                x2, y2 = at(k + 1)
                if (k + 1) % self.BLOCK_ROW:
                    out.append(f'<line class="sequence" x1="{x + self.BLOCK_W}" y1="{y + self.BLOCK_H // 2}" '
                               f'x2="{x2 - 2}" y2="{y2 + self.BLOCK_H // 2}" stroke="#555" marker-end="url(#arrow)"/>')
            out.append(self.block(block, x, y, any(s.order in late for s in block.steps)))
        first = {b.first.order: k for k, b in enumerate(shown)}
        for change in changes:
            x, y = at(first[change.order])
            out.append(f'<g class="tool-change" data-order="{change.order}" data-from="{escape(change.before.ref)}" '
                       f'data-to="{escape(change.after.ref)}"><title>tool change before step {change.order}: '
                       f'{escape(change.before.label)} -&gt; {escape(change.after.label)}</title>'
                       f'<line x1="{x - self.GAP // 2}" y1="{y - 6}" x2="{x - self.GAP // 2}" y2="{y + self.BLOCK_H + 6}" '
                       f'stroke="#d62728" stroke-width="2"/><text x="{x - self.GAP // 2}" y="{y - 9}" '
                       f'text-anchor="middle" fill="#d62728" font-weight="bold">T</text></g>')
        out += self._legend(legend_y, steps)
        out.append("</svg>")
        return "\n".join(out) + "\n"

    def block(self, b: Block, x: int, y: int, late: bool) -> str:
        s = b.first
        setup = s.setup.label if s.setup else "(no setup)"
        tool = f"{s.tool.label} {s.tool.ref}" if s.tool else "no tool"
        steps = f"step {s.order}" if len(b.steps) == 1 else f"steps {s.order}-{b.last.order} ({len(b.steps)})"
        refs = ", ".join(f"{t.order}. {t.workingstep.label} {t.workingstep.ref}" for t in b.steps[:20])
        more = f", ... ({len(b.steps) - 20} more)" if len(b.steps) > 20 else ""
        cls = "block precedence" if late else "block"
        ink = _ink(self.colour(s))
        stroke = ' stroke="#d62728" stroke-width="3"' if late else ' stroke="#333"'

        def cut(text: str, n: int = 25) -> str:
            return text if len(text) <= n else text[:n - 1] + "…"

        return (f'<g class="{cls}" data-first="{s.order}" data-last="{b.last.order}" data-steps="{len(b.steps)}" '
                f'data-setup="{escape(setup)}" data-tool="{escape(s.tool.ref) if s.tool else ""}" '
                f'data-tool-body="{escape(s.tool_body)}"><title>{escape(setup)}; tool {escape(tool)} '
                f'({escape(s.tool_body)}); {escape(refs + more)}'
                f'{"; a finishing step runs before roughing on its feature" if late else ""}</title>'
                f'<rect x="{x}" y="{y}" width="{self.BLOCK_W}" height="{self.BLOCK_H}" rx="5" fill="{self.colour(s)}"'
                f'{stroke}/><text x="{x + 6}" y="{y + 16}" fill="{ink}" font-weight="bold">{escape(steps)}</text>'
                f'<text x="{x + 6}" y="{y + 34}" fill="{ink}">{escape(cut(tool))}</text>'
                f'<text x="{x + 6}" y="{y + 52}" fill="{ink}">{escape(cut(setup))}</text></g>')


def _wrap(text: str, width: int, lines: int) -> list[str]:
    """``text`` in at most ``lines`` lines of ``width`` characters, broken at spaces; the last line
    ends with an ellipsis only when even that is not enough (the box's tooltip has it all)."""
    import textwrap

    out = textwrap.wrap(text, width, break_long_words=True) or [""]
    if len(out) > lines:
        rest = " ".join(out[lines - 1:])
        out = out[:lines - 1] + [rest[:width - 1] + "\u2026"]
    return out


def png(svg: str) -> bytes:
    """The picture as PNG; needs the ``png`` extra (``pip install 'stepnc-graph[png]'``, cairosvg)."""
    try:
        import cairosvg
    except (ImportError, OSError):  # not installed, or no cairo library on the system
        raise ImportError("PNG output needs cairosvg: pip install 'stepnc-graph[png]'") from None
    return bytes(cairosvg.svg2png(bytestring=svg.encode("utf-8")))
