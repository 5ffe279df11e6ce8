"""A stand-in for a viser client's GuiApi: records every control added (label -> handle), so that
tests can read the panel render.viewer.gui builds without a browser."""

from __future__ import annotations

import contextlib


class Handle:
    """A control: its value, options (dropdowns), disabled / visible flags and callbacks."""

    def __init__(self, kind: str, label: str, value=None, options=(), **kw):
        self.kind, self.label, self.value, self.options = kind, label, value, tuple(options)
        self.disabled, self.visible, self.hint = kw.get("disabled", False), kw.get("visible", True), kw.get("hint")
        self.callbacks = []

    def on_update(self, fn):
        self.callbacks.append(fn)
        return fn

    on_click = on_update

    def set(self, value) -> None:
        """Change the value as a user would (the update callbacks run)."""
        self.value = value
        for fn in self.callbacks:
            fn(None)


class FakeGui:
    """The GuiApi calls render.viewer.gui makes; ``handles`` maps each label to its handle."""

    def __init__(self):
        self.handles: dict[str, Handle] = {}

    def _add(self, kind, label, value=None, options=(), **kw) -> Handle:
        h = Handle(kind, label, value, options, **kw)
        self.handles[label] = h
        return h

    @contextlib.contextmanager
    def add_folder(self, label):
        yield

    def add_dropdown(self, label, options, initial_value=None, **kw):
        return self._add("dropdown", label, initial_value if initial_value is not None else options[0], options, **kw)

    def add_slider(self, label, lo, hi, step, initial_value, **kw):
        return self._add("slider", label, initial_value, **kw)

    def add_checkbox(self, label, initial_value, **kw):
        return self._add("checkbox", label, initial_value, **kw)

    def add_number(self, label, initial_value, **kw):
        return self._add("number", label, initial_value, **kw)

    def add_button(self, label, **kw):
        return self._add("button", label, **kw)

    def add_progress_bar(self, value, **kw):
        return self._add("progress", "progress", value, **kw)

    def add_markdown(self, content, **kw):
        h = self._add("markdown", f"markdown {len(self.handles)}", content, **kw)
        h.content = content
        return h
