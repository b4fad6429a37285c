from setuptools import find_packages, setup

package_name = "efficient_comm"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={"efficient_comm.examples": ["*.yaml"], "efficient_comm": ["py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", ["efficient_comm/examples/demo.yaml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="efficient_comm developers",
    maintainer_email="dev@example.com",
    description="Dependency-injected node handles, by-reference composition, consecutive executor.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "container = efficient_comm.cli:container",
            "standalone = efficient_comm.cli:standalone",
            "demo = efficient_comm.examples.demo:main",
            "camera = efficient_comm.examples.nodes:camera",
        ],
        "efficient_comm.components": [
            "camera = efficient_comm.examples.pipeline:Camera",
            "spot_detector = efficient_comm.examples.pipeline:SpotDetector",
            "tracker = efficient_comm.examples.pipeline:Tracker",
            "monitor = efficient_comm.examples.pipeline:Monitor",
        ],
    },
)
