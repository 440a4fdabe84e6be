"""Build hook: the wheel carries the course (lessons, exercises, demos, benchmarks) as package data.

The folders stay at the repository's top level, where instructors edit them; building a wheel
copies them by pattern (:data:`coursekit.course.PACKAGED`) into ``coursekit/_course/``. Every
other setting is in ``pyproject.toml``.
"""

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent
PACKAGED = {"lessons": "*.ipynb", "exercises": "*.ipynb", "demos": "*.ipynb", "benchmarks": "*.py", "benchmarks/data": "*.json"}  # = coursekit.course.PACKAGED


class build_py_with_course(build_py):
    def run(self):
        super().run()
        if getattr(self, "editable_mode", False):
            return  # an editable install reads the course from the checkout
        dest = Path(self.build_lib) / "coursekit" / "_course"
        for folder, pattern in PACKAGED.items():
            found = sorted((HERE / folder).glob(pattern))
            if folder == "lessons" and not found:
                raise SystemExit(f"coursekit build: no {pattern} in {HERE / folder}; the wheel would carry no course")
            for path in found:
                (dest / folder).mkdir(parents=True, exist_ok=True)
                shutil.copyfile(path, dest / folder / path.name)


setup(cmdclass={"build_py": build_py_with_course})
