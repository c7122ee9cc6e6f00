"""The build step pyproject.toml cannot declare: the wheel carries the repository's ``policies/``
(the shipped policies, their ONNX twins and manifests) as ``uavlink/shipped``, so an installed
package flies them from any folder. One copy stays in the repository; the checkout's code finds it
where it lies (``uavlink.policies.loader.shipped_root``)."""

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

SHIPPED = ("*.zip", "*.onnx", "*.json")


class BuildPyWithPolicies(build_py):
    def run(self) -> None:
        super().run()
        source = Path(__file__).resolve().parent / "policies"
        target = Path(self.build_lib) / "uavlink" / "shipped"
        if target.exists():
            shutil.rmtree(target)
        for pattern in SHIPPED:
            for path in source.rglob(pattern):
                destination = target / path.relative_to(source)
                destination.parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(path, destination)


setup(cmdclass={"build_py": BuildPyWithPolicies})
