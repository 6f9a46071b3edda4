"""The API reference site's generators (docs/): an env card for every registered task (one registered
here included), the CLI reference for every subcommand, an API page for every public module, the
includes of the repository's Markdown, the docstring-to-Markdown rules, and the pages' Python examples.
The site itself is built strictly by ``make test`` (``mkdocs build --strict``)."""

from __future__ import annotations

import importlib
import re
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest
import torch
from tensordict import TensorDictBase

from falcon_rl.cli import build_parser
from falcon_rl.envs.tasks import Task, TaskConfig, TaskSpec, register_task, task_names, unregister_task

DOCS = Path(__file__).resolve().parents[1] / "docs"
ROOT = DOCS.parent


def docs_module(name: str):
    """A module of docs/ (the site's generators are plain scripts beside its pages)."""
    if str(DOCS) not in sys.path:
        sys.path.insert(0, str(DOCS))
    return importlib.import_module(name)


# ------------------------------------------------------------------------------------------ a late task
@dataclass
class HoldConfig(TaskConfig):
    episode_seconds: float = 0.2


class HoldTask(Task):
    """Observation [h / 100]; action [throttle]; reward 0."""

    name = "docs_hold"
    observation_dim = 1
    action_dim = 1
    observation_clip = 2.0
    action_channels = (3,)

    def sample_initial(self, mask: torch.Tensor) -> dict[str, torch.Tensor]:
        return {**self.trim_initial(), "height": torch.full((self.num_envs,), 50.0, dtype=self.dtype)}

    def observe(self, state: TensorDictBase) -> torch.Tensor:
        return (state["height"].reshape(self.num_envs, 1) / 100.0).clamp(-2.0, 2.0)

    def reward(self, state: TensorDictBase, action: torch.Tensor) -> torch.Tensor:
        return torch.zeros(self.num_envs, dtype=self.dtype)

    def info(self) -> dict[str, torch.Tensor]:
        return {}


@pytest.fixture
def late_task():
    spec = register_task(TaskSpec(name="docs_hold", task=HoldTask, config=HoldConfig,
                                  gym_id="falcon_rl_docs/Hold-v0", title="Docs hold"))
    yield spec
    unregister_task(spec.name)


def test_env_cards_cover_every_registered_task(late_task) -> None:
    pages = docs_module("gen_env_cards").env_cards()
    names = task_names()
    assert "docs_hold" in names
    assert set(pages) == {"tasks/index.md", *(f"tasks/{name}.md" for name in names)}
    for name in names:
        card = pages[f"tasks/{name}.md"]
        spec_gym_id = {"docs_hold": "falcon_rl_docs/Hold-v0"}.get(name)
        assert f"(`{name}`)" in card.splitlines()[0]
        assert "## Keys and specs" in card and "| `observation` | observation | [N, " in card
        assert "| `action` | action |" in card and "| **horizon** |" in card
        assert "| **control rate** |" in card and "| **termination** |" in card
        if spec_gym_id:
            assert spec_gym_id in card
        assert f"]({name}.md)" in pages["tasks/index.md"]
    hold = pages["tasks/docs_hold.md"]
    assert "1 entries, clipped to +-2.0" in hold and "0.2 s = " in hold
    assert "No evaluation protocol is registered" in hold


def test_env_card_numbers_come_from_the_env() -> None:
    from falcon_rl.envs import make_env

    cards = docs_module("gen_env_cards")
    env = make_env("altitude", num_envs=1, backend="torch", seed=0)
    facts = cards.env_facts(env, None)
    assert facts["steps"] == env.max_episode_steps
    assert facts["control_dt"] == pytest.approx(env.control_dt)
    assert cards.spec_text(env.action_spec) == "Bounded [-1.0, 1.0]"
    assert cards.shape_text(env.observation_spec["observation"].shape) == "[N, 11]"


def test_cli_reference_has_every_subcommand() -> None:
    gen_cli = docs_module("gen_cli")
    parser = build_parser()
    page = gen_cli.render_cli(parser)
    commands = gen_cli.subcommands(parser)
    assert commands
    for name, _, sub in commands:
        assert f"## `{parser.prog} {name}`" in page
        assert sub.format_usage().split()[1] in page
    assert page.count("```text") == 1 + sum(1 for _ in gen_cli._walk(parser, ()))


def test_api_pages_cover_every_public_module() -> None:
    gen_api = docs_module("gen_api")
    pages = gen_api.api_pages()
    documented = {line.split()[1] for page in pages for line in page.markdown.splitlines()
                  if line.startswith("::: ")}
    package = gen_api.package_dir()
    for path in package.rglob("*.py"):
        parts = path.relative_to(package).with_suffix("").parts
        if any(part.startswith("_") for part in parts[:-1]) or parts[0] in gen_api.SKIPPED:
            continue
        if parts[-1] == "__init__":
            parts = parts[:-1]
        elif parts[-1].startswith("_"):
            continue
        assert ".".join((gen_api.PACKAGE, *parts)) in documented, path
    assert pages[0].path == "api/index.md"
    assert len({page.path for page in pages}) == len(pages)


def test_includes_resolve() -> None:
    includes = docs_module("includes")
    found = 0
    for page in DOCS.rglob("*.md"):
        for match in includes.DIRECTIVE.finditer(page.read_text(encoding="utf-8")):
            found += 1
            assert includes.included(match["path"], match["section"]).strip(), (page.name, match.group(0))
    assert found >= 5
    with pytest.raises(ValueError, match="no section"):
        includes.included("README.md", "No such section")
    with pytest.raises(ValueError, match="missing file"):
        includes.included("NO_SUCH_FILE.md", None)


def test_readme_sections() -> None:
    section = docs_module("includes").section
    readme = "# T\n\nintro\n\n## A\n\na text\n\n```\n## not a heading\n```\n\n### A.1\n\nsub\n\n## B\n\nb\n"
    assert section(readme, "") == "intro"
    assert section(readme, "A") == "a text\n\n```\n## not a heading\n```\n\n### A.1\n\nsub"
    assert section(readme, "B") == "b"
    assert section(readme, "C") is None
    indented = docs_module("includes").expand("x\n    <!-- include README.md \"Two commands\" -->\n", print)
    assert "\n    ```bash" in indented


def test_docstrings_to_markdown() -> None:
    prose = docs_module("prose")
    resolve = {"Simulator": "falcon_rl.physics.simulator.Simulator"}.get
    out = prose.to_markdown("See :class:`Simulator` and :func:`~falcon_rl.envs.make_env`; h* and V_a* "
                            "stay, <Task> is text, ``a*b`` is code.", resolve)
    simulator = '<autoref identifier="falcon_rl.physics.simulator.Simulator" optional><code>Simulator</code>'
    assert simulator in out
    assert '<autoref identifier="falcon_rl.envs.make_env" optional><code>make_env</code>' in out
    assert r"h\* and V_a\*" in out and "&lt;Task>" in out and "``a*b``" in out

    table = prose.to_markdown("Rows:\n\n===  =====\nkey  value\n===  =====\na    one\n     more\n"
                              "b|c  two\n===  =====")
    assert "| key | value |\n|---|---|\n| a | one more |\n| b\\|c | two |" in table

    summary = prose.to_markdown("First sentence\nwrapped.\n\nMore\nlines.")
    assert summary == "First sentence wrapped.\n\nMore\nlines."

    literal = prose.to_markdown("Keys:\n    observation   [N, D]\n    action        [N, A]\nAfter.")
    assert literal == "Keys:\n\n    observation   [N, D]\n    action        [N, A]\n\nAfter."

    args = prose.to_markdown("Step.\n\nArgs:\n    a, b: [N] inputs,\n        continued.\n    c: more.\n\n"
                             "Returns:\n    [N] output.")
    assert "**Args**\n\n- `a`, `b`: [N] inputs, continued.\n- `c`: more." in args
    assert "**Returns**\n\n[N] output." in args


def _examples() -> list:
    params = []
    for page in ("getting-started.md", "envs.md"):
        text = (DOCS / page).read_text(encoding="utf-8")
        for index, block in enumerate(re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)):
            slow = "from_env" in block  # the LQR design takes seconds
            params.append(pytest.param(block, id=f"{page}[{index}]",
                                       marks=[pytest.mark.slow] if slow else []))
    return params


@pytest.mark.parametrize("block", _examples())
def test_page_examples_run(block: str) -> None:
    exec(compile(block, "docs example", "exec"), {"__name__": "docs_example"})
