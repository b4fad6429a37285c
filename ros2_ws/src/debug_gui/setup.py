from setuptools import find_packages, setup

package_name = "debug_gui"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["py.typed", "ui/*.js"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{package_name}"]),
        (f"share/{package_name}", ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="efficient_comm dev",
    maintainer_email="dev@example.com",
    description="Debugging GUI for teams of robots in the browser: robot hub, views, server.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "debug_gui = debug_gui.server:main",
            "debug_gui_demo = debug_gui.demo:main",
        ],
    },
)
