"""Where a figure's texts land once drawn: outside the figure, or over one another (the
study figures' and the gallery's tests)."""

from __future__ import annotations


def drawn_texts(fig):
    """``(text, its extent in pixels)`` of every text a draw of ``fig`` puts on the canvas
    (visible and not empty; ticks outside the view and hidden axes' texts are not drawn)."""
    import matplotlib.text as mtext
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    drawn = []
    original = mtext.Text.draw

    def draw(self, renderer):
        if self.get_visible() and self.get_text():
            drawn.append(self)
        return original(self, renderer)

    FigureCanvasAgg(fig)
    mtext.Text.draw = draw
    try:
        fig.canvas.draw()
    finally:
        mtext.Text.draw = original
    renderer = fig.canvas.get_renderer()
    return [(t, t.get_window_extent(renderer)) for t in drawn]


def text_faults(fig):
    """The drawn texts that reach outside the figure, and the pairs that overlap (by more
    than a pixel each way)."""
    texts = drawn_texts(fig)
    box = fig.bbox
    faults = [("outside", t.get_text()) for t, b in texts
              if b.x0 < box.x0 - 1 or b.y0 < box.y0 - 1 or b.x1 > box.x1 + 1 or b.y1 > box.y1 + 1]
    for i, (t, b) in enumerate(texts):
        for u, c in texts[i + 1:]:
            if min(b.x1, c.x1) - max(b.x0, c.x0) > 1 and min(b.y1, c.y1) - max(b.y0, c.y0) > 1:
                faults.append(("overlap", t.get_text(), u.get_text()))
    return faults
