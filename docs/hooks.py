"""MkDocs hooks of the site (``hooks:`` in mkdocs.yml): generated pages and includes.

- Generated at build time, never written to the repository: the API reference (``gen_api.py``), the
  CLI reference (``gen_cli.py``, from ``falcon_rl.cli.build_parser()``) and one env card per
  registered task (``gen_env_cards.py``). The nav entries ``api/index.md`` and ``tasks/index.md``
  are expanded to the generated pages.
- Includes of the repository's own Markdown (``includes.py``): ``<!-- include README.md "Physics
  summary" -->`` on a page stands for that section of the file.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

# gen_*: siblings of this file. MkDocs puts this file's folder on sys.path only while it loads the
# file, so they are imported now.
import gen_api
import gen_cli
import gen_env_cards
import includes
from mkdocs.structure.files import File

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent

log = logging.getLogger("mkdocs.plugins.falcon_rl_docs")


def on_page_markdown(markdown: str, page, config, files) -> str:
    return includes.expand(markdown, lambda reason: log.warning("%s: %s", page.file.src_uri, reason))


def _expand(nav: list, index: str, entries: list[tuple[str, str]]) -> None:
    """Replace the nav value ``index`` (a page) by a section: that page first, then ``entries``."""
    for position, item in enumerate(nav):
        if isinstance(item, dict):
            for title, value in item.items():
                if value == index:
                    item[title] = [{"Overview": index}, *({name: path} for name, path in entries)]
                elif isinstance(value, list):
                    _expand(value, index, entries)
        elif item == index:
            nav[position] = {"Overview": index}


def on_files(files, config):
    started = time.perf_counter()
    pages: dict[str, str] = {}
    api = gen_api.api_pages()
    pages.update({page.path: page.markdown for page in api})
    pages["cli.md"] = gen_cli.render_cli()
    cards = gen_env_cards.env_cards()
    pages.update(cards)
    for path, content in pages.items():
        if files.get_file_from_path(path) is not None:
            log.warning("generated page %s would replace a file of the same name in docs/", path)
            continue
        files.append(File.generated(config, path, content=content))
    if config.nav is not None:
        _expand(config.nav, "api/index.md", [(page.title, page.path) for page in api[1:]])
        _expand(config.nav, "tasks/index.md",
                [(_title(content), path) for path, content in cards.items() if path != "tasks/index.md"])
    log.info("falcon_rl docs: %d pages generated in %.1f s", len(pages), time.perf_counter() - started)
    return files


def _title(markdown: str) -> str:
    first = markdown.lstrip().splitlines()[0]
    return first.lstrip("# ").replace("`", "").strip()
